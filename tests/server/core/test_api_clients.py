"""The caps of anonymous clients per address (server/core/clients.py) and the strict Host check, through a real
server on loopback: each client here connects from an address of its own in 127.0.0.0/8 (the server sees the
connection's peer), so one address's caps are seen not to touch another's. The caps' windows, with an injectable
clock, are in test_clients.py; a server that requires an identity, in test_api_identity.py."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest

from tests.support.api import INSTRUCTOR, Server, bearer, long_scene, student_token, tiny_scene, wait_for

TEACHER = bearer(INSTRUCTOR)
CAPS = {
    "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR,
    "TRACER_MAX_NEW_TOKENS_PER_ADDRESS": "3",
    "TRACER_MAX_QUEUED_PER_ADDRESS": "4",
    "TRACER_SHARED_NETWORKS": "127.0.0.4/32",  # one address standing for a class of two
    "TRACER_SHARED_NETWORK_CLIENTS": "2",
    "TRACER_MAX_JOINS_PER_ADDRESS": "2",
}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("clients") / "data", workers=1, env=CAPS) as s:
        yield s


def client_at(server: Server, address: str, token: str | None = None) -> httpx.Client:
    """A client of `server` connecting from `address` (any of 127.0.0.0/8 reaches the server's 127.0.0.1)."""
    transport = httpx.HTTPTransport(local_address=address)
    return httpx.Client(base_url=server.url, transport=transport, timeout=60, headers=bearer(token) if token else {})


def post_job(client: httpx.Client, **body) -> httpx.Response:
    return client.post("/api/jobs", json={"scene": tiny_scene(), **body})


@pytest.fixture
def busy(server):
    """The one worker held by a long render of the instructor's (known: no cap), so that jobs stay waiting;
    cancelled at the end, and every job left waiting with it."""
    teacher = client_at(server, "127.0.0.1", INSTRUCTOR)
    r = teacher.post("/api/jobs", json={"scene": long_scene(spp=256), "lane": "interactive"})
    assert r.status_code == 202, r.text
    long_id = r.json()["id"]
    wait_for(lambda: teacher.get(f"/api/jobs/{long_id}").json()["status"] == "running", 60, "the long render")
    yield teacher
    for kind in ("render", "raytree"):
        for j in teacher.get("/api/jobs", params={"status": "queued", "kind": kind}).json()["jobs"]:
            teacher.delete(f"/api/jobs/{j['id']}")
    teacher.delete(f"/api/jobs/{long_id}")
    wait_for(lambda: teacher.get(f"/api/jobs/{long_id}").json()["finished"], 60, "the long render to stop")
    teacher.close()


def test_clients_one_address_gets_so_many_new_tokens(server):
    """1 071 jobs without a token were each given a new token: now an address gets three (the setting) and a 429
    naming it, with Retry-After; another address, and the tokens already given, go on."""
    with client_at(server, "127.0.0.2") as flood, client_at(server, "127.0.0.3") as other:
        tokens = []
        for _ in range(3):
            r = post_job(flood)
            assert r.status_code == 202, r.text
            tokens.append(r.json()["token"])
        assert len(set(tokens)) == 3
        r = post_job(flood)
        assert r.status_code == 429, r.text
        assert 1 <= int(r.headers["retry-after"]) <= 3600
        [error] = r.json()["errors"]
        assert error["path"] == "Authorization"
        assert "TRACER_MAX_NEW_TOKENS_PER_ADDRESS" in error["message"]
        assert "127.0.0.2" in error["message"], error
        assert post_job(flood, priority=1).status_code == 429  # still
        assert post_job(other).status_code == 202  # another address has its own
        kept = flood.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(tokens[0]))
        assert kept.status_code == 202
        assert kept.json()["token"] is None  # a token given before still works


def test_clients_an_invalid_scene_costs_no_token(server):
    with client_at(server, "127.0.0.7") as c:
        bad = tiny_scene()
        bad["sampler"]["spp"] = 0
        for _ in range(5):  # more than the cap: none of them was given a token
            assert post_job(c, scene=bad).status_code == 422
        assert post_job(c).status_code == 202


def test_clients_a_shared_network_address_stands_for_its_clients(server):
    """127.0.0.4 is in TRACER_SHARED_NETWORKS with two clients: twice one address's three tokens."""
    with client_at(server, "127.0.0.4") as nat:
        assert [post_job(nat).status_code for _ in range(7)] == [202] * 6 + [429]


def test_clients_an_address_has_so_many_jobs_waiting_without_a_known_identity(server, busy):
    """Tokens of its own making do not help a client past its address's cap; the instructor's do; a job that leaves
    the queue leaves room."""
    with client_at(server, "127.0.0.5") as c:
        ids = []
        for _ in range(4):
            r = c.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(student_token()))
            assert r.status_code == 202, r.text
            ids.append((r.json()["id"], r.request.headers["authorization"]))
        r = c.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(student_token()))
        assert r.status_code == 429
        assert r.headers["retry-after"] == "5"
        assert "TRACER_MAX_QUEUED_PER_ADDRESS" in r.json()["errors"][0]["message"]
        assert "127.0.0.5" in r.json()["errors"][0]["message"]
        assert c.post("/api/jobs", json={"scene": tiny_scene()}, headers=TEACHER).status_code == 202
        job_id, auth = ids[0]
        assert c.delete(f"/api/jobs/{job_id}", headers={"Authorization": auth}).status_code == 200
        assert c.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(student_token())).status_code == 202


def test_clients_an_anonymous_ray_tree_waits_behind_a_students(server, busy):
    """Ray trees without a token ran at priority 100 with no owner, ahead of everyone and under no cap: now they
    have an anonymous job's priority (0) and count under their address's cap, so a student's (their token's: 100)
    goes first and a fifth from the address is refused at once."""
    scene = tiny_scene()
    with ThreadPoolExecutor(6) as pool, client_at(server, "127.0.0.6") as anon:
        trees = [pool.submit(anon.post, "/api/raytree", json={"scene": scene, "x": 3, "y": 4}) for _ in range(4)]

        def waiting() -> list[dict]:
            return busy.get("/api/jobs", params={"kind": "raytree", "status": "queued"}).json()["jobs"]

        wait_for(lambda: len(waiting()) == 4, 30, "four anonymous ray trees waiting")
        fifth = anon.post("/api/raytree", json={"scene": scene, "x": 3, "y": 4})
        assert fifth.status_code == 429
        assert "TRACER_MAX_QUEUED_PER_ADDRESS" in fifth.json()["errors"][0]["message"]
        student = client_at(server, "127.0.0.1", student_token())
        mine = pool.submit(student.post, "/api/raytree", json={"scene": scene, "x": 5, "y": 6})
        queued = wait_for(lambda: len(w := waiting()) == 5 and w, 30, "the student's ray tree waiting")
        by_pixel = {j["name"].split(" of ")[0]: j for j in queued}
        assert by_pixel["ray tree (5, 6)"]["priority"] == 100
        assert by_pixel["ray tree (5, 6)"]["queue"]["position"] == 1  # ahead of the four anonymous ones
        assert [j["priority"] for j in queued if j["name"].startswith("ray tree (3, 4)")] == [0] * 4
        own = student.get("/api/jobs", params={"kind": "raytree"}).json()["jobs"]
        assert [j["name"][:15] for j in own] == ["ray tree (5, 6)"]  # the anonymous ones are not the student's
        long_id = busy.get("/api/jobs", params={"status": "running"}).json()["jobs"][0]["id"]
        busy.delete(f"/api/jobs/{long_id}")  # the worker is free: every tree is traced
        assert mine.result().status_code == 200, mine.result().text
        assert [t.result().status_code for t in trees] == [200] * 4
        student.close()


@pytest.mark.parametrize(
    "host", ["127.0.0.1:80@evil.com", "127.0.0.1:99999", "127.0.0.1:0", "127.0.0.1:", "127.0.0.1:8x", "[::1]x"]
)
def test_clients_a_host_header_with_anything_but_a_port_after_the_name_is_400(server, host):
    r = server.client.get("/api/health", headers={"Host": host})
    assert r.status_code == 400, (host, r.text)
    assert r.json()["errors"][0]["path"] == "Host"


def test_clients_a_host_header_with_a_port_is_served(server):
    for host in (f"127.0.0.1:{server.port}", "localhost:65535", "[::1]:1", "LOCALHOST.", "127.0.0.1"):
        assert server.client.get("/api/health", headers={"Host": host}).status_code == 200, host


def open_assignment(server: Server, **policy) -> str:
    """An open assignment of the repository's example (anyone with its link joins by a name)."""
    import json

    from tests.support.scene import ROOT

    grading = ROOT / "scenes" / "grading"
    spec = json.loads((grading / "assignment.json").read_text())
    spec["reference"]["scene"] = json.loads((grading / "reference.json").read_text())
    with client_at(server, "127.0.0.1", INSTRUCTOR) as teacher:
        body = {"spec": spec, "deadline": "2030-01-01T00:00:00Z", "open": True, **policy}
        r = teacher.post("/api/assignments", json=body)
        assert r.status_code == 201, r.text
        return r.json()["id"]


def test_clients_a_joined_identity_counts_against_its_address(server, busy):
    """A name anyone may type (an open assignment's join) is not a known identity for the address's cap: two joined
    tokens of one address have its 4 waiting jobs between them, and the next is a 429 naming
    TRACER_MAX_QUEUED_PER_ADDRESS; a roster's student at the same address is not held by it."""
    aid = open_assignment(server)
    with client_at(server, "127.0.0.7") as c:
        a, b = (c.post(f"/api/assignments/{aid}/join", json={"name": n}).json()["token"] for n in ("Ann", "Bo"))
        for token in (a, a, a, b):
            r = c.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(token))
            assert r.status_code == 202, r.text
        r = c.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(b))
        assert r.status_code == 429, r.text
        assert "TRACER_MAX_QUEUED_PER_ADDRESS" in r.json()["errors"][0]["message"]
        roster = c.post(
            f"/api/assignments/{aid}/roster", content="id,name,email\nr1,Rita,\n",
            headers={**TEACHER, "Content-Type": "text/csv"},
        )  # fmt: skip
        listed = roster.json()["students"][0]["token"]
        r = c.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(listed))
        assert r.status_code == 202, r.text


def test_clients_an_address_joins_so_many_times(server):
    """Joins of one address: TRACER_MAX_JOINS_PER_ADDRESS (2 here) in the window, then a 429 naming it with
    Retry-After; another address joins."""
    aid = open_assignment(server)
    with client_at(server, "127.0.0.8") as c, client_at(server, "127.0.0.9") as other:
        for name in ("Cy", "Di"):
            assert c.post(f"/api/assignments/{aid}/join", json={"name": name}).status_code == 200
        r = c.post(f"/api/assignments/{aid}/join", json={"name": "Ed"})
        assert r.status_code == 429, r.text
        assert "TRACER_MAX_JOINS_PER_ADDRESS" in r.json()["errors"][0]["message"]
        assert int(r.headers["retry-after"]) > 0
        assert other.post(f"/api/assignments/{aid}/join", json={"name": "Flo"}).status_code == 200
