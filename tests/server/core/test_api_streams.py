"""Open event streams per token and per address (server/core/clients.py `StreamCaps`), through a real server on
loopback with no render worker (every job stays queued, so each stream stays open): one token opened 2 000
streams and others got 503; now a token, and an address, get a 429 with Retry-After past their cap, while
another address, and the instructor, still get theirs. Each client connects from an address of its own in
127.0.0.0/8."""

from __future__ import annotations

import contextlib
import json

import httpx
import pytest

from tests.support.api import INSTRUCTOR, Server, bearer, student_token, tiny_scene, wait_for
from tests.support.scene import ROOT

TEACHER = bearer(INSTRUCTOR)
ENV = {
    "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR,
    "TRACER_MAX_STREAMS_PER_TOKEN": "3",
    "TRACER_MAX_STREAMS_PER_ADDRESS": "5",
}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("streams") / "data", workers=0, env=ENV) as s:
        yield s


def client_at(server: Server, address: str) -> httpx.Client:
    return httpx.Client(base_url=server.url, transport=httpx.HTTPTransport(local_address=address), timeout=30)


def job_of(http: httpx.Client, token: str) -> str:
    r = http.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(token))
    assert r.status_code == 202, r.text
    return r.json()["id"]


@contextlib.contextmanager
def opened(http: httpx.Client, url: str, token: str):
    """An event stream held open: its response once its first line came (a 429's response as it is). Its lines'
    iterator is kept: a line iterator that is collected closes its response."""
    with http.stream("GET", url, headers=bearer(token)) as r:
        if r.status_code == 200:
            r.lines = r.iter_lines()
            assert next(r.lines).startswith("retry:")
        yield r


def test_streams_a_token_and_an_address_have_so_many_open(server):
    with client_at(server, "127.0.0.2") as http, client_at(server, "127.0.0.3") as elsewhere:
        me, other = student_token(), student_token()
        url = f"/api/jobs/{job_of(http, me)}/events"
        with contextlib.ExitStack() as held:
            for _ in range(3):
                assert held.enter_context(opened(http, url, me)).status_code == 200
            with opened(http, url, me) as r:
                assert r.status_code == 429
                r.read()
                assert int(r.headers["retry-after"]) > 0
                [error] = r.json()["errors"]
                assert "TRACER_MAX_STREAMS_PER_TOKEN" in error["message"]
                assert "3 event streams" in error["message"]
            theirs = f"/api/jobs/{job_of(http, other)}/events"
            for _ in range(2):  # another token of the same address: the address's 5 in all
                assert held.enter_context(opened(http, theirs, other)).status_code == 200
            with opened(http, theirs, other) as r:
                assert r.status_code == 429
                r.read()
                message = r.json()["errors"][0]["message"]
                assert "TRACER_MAX_STREAMS_PER_ADDRESS" in message and "127.0.0.2" in message, message
            far = student_token()  # another address has its own
            with opened(elsewhere, f"/api/jobs/{job_of(elsewhere, far)}/events", far) as r:
                assert r.status_code == 200
            with opened(elsewhere, url, INSTRUCTOR) as r:  # the instructor's are not counted
                assert r.status_code == 200

        def again() -> bool:  # the closed streams gave their room back (the server sees each client leave)
            with opened(http, url, me) as r:
                return r.status_code == 200

        wait_for(again, 10, "the streams' room given back")


def test_streams_a_submission_s_stream_counts_too(server):
    """The course's submission stream (GET /api/assignments/{aid}/submissions/{sid}/events) shares the caps."""
    grading = ROOT / "scenes" / "grading"
    spec = json.loads((grading / "assignment.json").read_text())
    spec["reference"]["scene"] = json.loads((grading / "reference.json").read_text())
    with client_at(server, "127.0.0.4") as http:
        body = {"spec": spec, "deadline": "2030-01-01T00:00:00Z", "open": True}
        r = http.post("/api/assignments", json=body, headers=TEACHER)
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        me = http.post(f"/api/assignments/{aid}/join", json={"name": "Sam"}).json()["token"]
        scene = json.loads((grading / "class" / "alice.json").read_text())
        r = http.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(me))
        assert r.status_code == 202, r.text
        url = f"/api/assignments/{aid}/submissions/{r.json()['id']}/events"
        job_url = f"/api/jobs/{job_of(http, me)}/events"
        with contextlib.ExitStack() as held:
            for u in (url, url, job_url):
                assert held.enter_context(opened(http, u, me)).status_code == 200
            for u in (url, job_url):
                with opened(http, u, me) as r:
                    assert r.status_code == 429, u
