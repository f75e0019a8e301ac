"""TRACER_REQUIRE_IDENTITY (server/api/deps.py `get_client`): jobs, ray trees, validation and samples only for a
known identity, a token on some assignment's roster (an open assignment's join included) or the instructor's;
and joining an open assignment is a new token of its address (server/core/clients.py). The app runs in a
TestClient without workers: a ray tree that passes the identity check gets the 503 of no worker."""

from __future__ import annotations

import json

import pytest

from tests.support.api import INSTRUCTOR, api_client, bearer, student_token, tiny_scene
from tests.support.scene import ROOT

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
    assert error["path"] == "Authorization"
    assert "open your assignment's link first" in error["message"]
    assert "TRACER_REQUIRE_IDENTITY" in error["message"]
    assert r.headers["www-authenticate"].startswith("Bearer")


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
        assert tree.status_code == 503
        assert "no render worker" in tree.text  # past the identity check
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
    assert refused.status_code == 429
    assert int(refused.headers["retry-after"]) > 0
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


def test_identity_an_open_assignment_takes_so_many_joined_students(tmp_path):
    """TRACER_MAX_JOINS_PER_ASSIGNMENT (2 here): the third join is a 403 naming it; another open assignment still
    takes its own; a refused join costs the address no join."""
    with api_client(
        tmp_path / "data", workers=0, token=None, instructor_token=INSTRUCTOR, max_joins_per_assignment=2
    ) as c:
        full, other = publish(c, open=True), publish(c, open=True)
        for name in ("Ann", "Bo"):
            assert c.post(f"/api/assignments/{full}/join", json={"name": name}).status_code == 200
        r = c.post(f"/api/assignments/{full}/join", json={"name": "Cy"})
        assert r.status_code == 403, r.text
        assert "TRACER_MAX_JOINS_PER_ASSIGNMENT" in r.json()["errors"][0]["message"]
        assert c.post(f"/api/assignments/{other}/join", json={"name": "Cy"}).status_code == 200
        assert c.app.state.caps.counts("testclient")[0] == 3  # the refused join's new token was given back


def test_identity_refused_tokens_back_off_their_address(tmp_path):
    """Failed authentication per address, on the caps' injectable clock: TRACER_MAX_AUTH_FAILURES (3 here) tokens
    that are not the instructor's where the instructor's is needed, or on no roster where one is, and the address's
    next requests with a token (the instructor's too) are a 429 naming the setting with Retry-After, until the
    oldest failure leaves TRACER_AUTH_FAILURE_WINDOW; requests without a token, and with a good token (the
    instructor's: test_identity_a_good_token_is_never_held_by_the_backoff), still pass."""
    from tests.support.api import Clock

    settings = dict(instructor_token=INSTRUCTOR, require_identity=True, max_auth_failures=3, auth_failure_window=60)
    with api_client(tmp_path / "data", workers=0, token=None, **settings) as c:
        c.app.state.caps.clock = clock = Clock(1000.0)
        assert c.get("/api/grade/schema", headers=bearer(student_token())).status_code == 401
        clock.now += 10
        assert c.get("/api/jobs", params={"scope": "all"}, headers=bearer(student_token())).status_code == 401
        assert c.post("/api/validate", json={"scene": tiny_scene()}, headers=bearer(student_token())).status_code == 401
        for headers in (bearer(student_token()), bearer(student_token())):
            r = c.get("/api/grade/schema", headers=headers)
            assert r.status_code == 429, r.text
            [error] = r.json()["errors"]
            assert error["path"] == "Authorization" and "TRACER_MAX_AUTH_FAILURES" in error["message"], error
            assert r.headers["retry-after"] == "50"  # the first failure leaves the window in 50 s
        assert c.get("/api/grade/schema", headers=TEACHER).status_code == 200  # a good token is never held
        assert c.get("/api/health").status_code == 200  # no token: not held
        clock.now += 50
        assert c.get("/api/grade/schema", headers=TEACHER).status_code == 200


def test_identity_a_good_token_is_never_held_by_the_backoff(tmp_path):
    """20 refused tokens from an address (the default TRACER_MAX_AUTH_FAILURES) hold up its further refused ones
    (429) for the window, never a good token: the admin's and a roster student's keep working."""
    from server.core.settings import Settings
    from tests.support.api import Clock

    default = Settings.model_fields["max_auth_failures"].default  # the harness lifts it: the default here
    settings = dict(
        instructor_token=INSTRUCTOR, require_identity=True, auth_failure_window=600, max_auth_failures=default
    )
    with api_client(tmp_path / "data", workers=0, token=None, **settings) as c:
        c.app.state.caps.clock = Clock(1000.0)
        aid = publish(c)
        text = "id,name,email\nada,Ada L,ada@example.edu\n"
        r = c.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv", **TEACHER})
        ada = bearer(r.json()["students"][0]["token"])
        for _ in range(c.app.state.settings.max_auth_failures):
            assert c.get("/api/grade/schema", headers=bearer(student_token())).status_code == 401
        assert c.get("/api/grade/schema", headers=bearer(student_token())).status_code == 429  # a further one
        assert c.get("/api/grade/schema", headers=TEACHER).status_code == 200
        assert c.get(f"/api/assignments/{aid}", headers=ada).status_code == 200
        assert c.post("/api/validate", json={"scene": tiny_scene()}, headers=ada).status_code == 200
