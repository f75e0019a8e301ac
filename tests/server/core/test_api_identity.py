"""TRACER_REQUIRE_IDENTITY (server/api/deps.py `get_client`): jobs, ray trees, validation and samples only for a
known identity, a token on some assignment's roster (an open assignment's join included) or the instructor's;
and joining an open assignment is a new token of its address (server/core/clients.py). The app runs in a
TestClient without workers: a ray tree that passes the identity check gets the 503 of no worker."""

from __future__ import annotations

import json

import pytest
from conftest import ROOT
from test_api_support import INSTRUCTOR, api_client, bearer, student_token, tiny_scene

TEACHER = bearer(INSTRUCTOR)
WORK = [  # every route that does work for a client: (path, body)
    ("/api/jobs", {"scene": tiny_scene()}),
    ("/api/raytree", {"scene": tiny_scene(), "x": 1, "y": 2}),
    ("/api/validate", {"scene": tiny_scene()}),
    ("/api/samples", {"scene": tiny_scene(), "x": 1, "y": 2}),
]


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    data = tmp_path_factory.mktemp("identity-data")
    settings = dict(instructor_token=INSTRUCTOR, require_identity=True, max_new_tokens_per_address=2)
    with api_client(data, workers=0, token=None, **settings) as c:
        yield c


def publish(app, **policy) -> str:
    grading = ROOT / "scenes" / "grading"
    spec = json.loads((grading / "assignment.json").read_text())
    spec["reference"]["scene"] = json.loads((grading / "reference.json").read_text())
    r = app.post("/api/assignments", json={"spec": spec, "deadline": "2030-01-01T00:00:00Z", **policy}, headers=TEACHER)
    assert r.status_code == 201, r.text
    return r.json()["id"]


@pytest.mark.parametrize(("path", "body"), WORK)
def test_identity_no_token_is_told_to_open_the_assignments_link(app, path, body):
    r = app.post(path, json=body)
    assert r.status_code == 401, r.text
    [error] = r.json()["errors"]
    assert error["path"] == "Authorization" and "open your assignment's link first" in error["message"]
    assert "TRACER_REQUIRE_IDENTITY" in error["message"] and r.headers["www-authenticate"].startswith("Bearer")


@pytest.mark.parametrize(("path", "body"), WORK)
def test_identity_a_token_on_no_roster_is_refused(app, path, body):
    r = app.post(path, json=body, headers=bearer(student_token()))
    assert r.status_code == 401, r.text
    assert "on no assignment's roster" in r.json()["errors"][0]["message"]
    assert 'error="invalid_token"' in r.headers["www-authenticate"]


def test_identity_a_roster_student_and_the_instructor_work(app):
    aid = publish(app)
    text = "id,name,email\nada,Ada L,ada@example.edu\n"
    r = app.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv", **TEACHER})
    assert r.status_code == 200, r.text
    ada = bearer(r.json()["students"][0]["token"])
    for who in (ada, TEACHER):
        job = app.post("/api/jobs", json={"scene": tiny_scene()}, headers=who)
        assert job.status_code == 202 and job.json()["token"] is None, job.text
        assert app.post("/api/validate", json={"scene": tiny_scene()}, headers=who).json()["valid"] is True
        samples = app.post("/api/samples", json={"scene": tiny_scene(), "x": 1, "y": 2}, headers=who)
        assert samples.status_code == 200, samples.text
        tree = app.post("/api/raytree", json={"scene": tiny_scene(), "x": 1, "y": 2}, headers=who)
        assert tree.status_code == 503 and "no render worker" in tree.text  # past the identity check
    assert app.get("/api/jobs", headers=ada).json()["count"] == 1  # the student's own job


def test_identity_joining_an_open_assignment_gives_one_and_counts_as_a_new_token(app):
    aid = publish(app, open=True)
    tokens = []
    for name in ("Zoë", "Yann"):
        r = app.post(f"/api/assignments/{aid}/join", json={"name": name})
        assert r.status_code == 200, r.text
        tokens.append(r.json()["token"])
    assert app.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(tokens[0])).status_code == 202
    refused = app.post(f"/api/assignments/{aid}/join", json={"name": "Xavier"})
    assert refused.status_code == 429 and int(refused.headers["retry-after"]) > 0
    assert "TRACER_MAX_NEW_TOKENS_PER_ADDRESS" in refused.json()["errors"][0]["message"]
    assert app.post(f"/api/assignments/{'0' * 32}/join", json={"name": "Wu"}).status_code == 429  # (the cap first)


def test_identity_one_person_on_their_own_machine_is_under_no_cap(tmp_path):
    """A loopback-only server without an instructor token is one person's: everyone is the instructor, a known
    identity, so a script of theirs that sends no token is never refused for it."""
    settings = dict(max_new_tokens_per_address=1, max_queued_per_address=1, require_identity=True)
    with api_client(tmp_path / "data", workers=0, token=None, **settings) as c:
        for _ in range(3):
            r = c.post("/api/jobs", json={"scene": tiny_scene()})
            assert r.status_code == 202 and r.json()["token"], r.text
