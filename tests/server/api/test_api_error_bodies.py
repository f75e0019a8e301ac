"""The error answers outside clients depend on, pinned whole (status, body, the headers that matter), one of each
kind of refusal the services raise: the services raise domain errors (server/core/errors.py) and server/api turns
them into these answers in one place (server/api/errors.py). A change of wording or status fails here first."""

from __future__ import annotations

import pytest

from tests.support.api import INSTRUCTOR, api_client, bearer


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """An app with an instructor token (so a missing or wrong token is refused); requests carry none unless given."""
    with api_client(tmp_path_factory.mktemp("bodies"), instructor_token=INSTRUCTOR, token=None) as c:
        yield c


STAFF = bearer(INSTRUCTOR)


def one(message: str, path: str = "") -> dict:
    return {"errors": [{"path": path, "message": message}]}


def test_error_bodies_unknown_job_is_404_at_id(client):
    r = client.get("/api/jobs/" + "a" * 32, headers=STAFF)
    assert r.status_code == 404
    assert r.json() == one(f"no job with id '{'a' * 32}'", "id")


def test_error_bodies_malformed_token_is_401_with_its_challenge(client):
    r = client.get("/api/jobs", headers={"Authorization": "Basic abc"})
    assert r.status_code == 401
    assert r.headers["www-authenticate"] == 'Bearer realm="tracer", error="invalid_request"'
    assert r.json()["errors"][0]["path"] == "Authorization"


def test_error_bodies_a_student_at_an_instructor_route_is_401_without_an_error_code(client):
    r = client.get("/api/grade/runs")
    assert r.status_code == 401
    assert r.headers["www-authenticate"] == 'Bearer realm="tracer"'
    assert r.json() == one("this needs the instructor's token: send 'Authorization: Bearer <token>'", "Authorization")


def test_error_bodies_a_course_made_twice_is_409(client):
    assert client.post("/api/courses", json={"id": "cg101", "name": "Graphics"}, headers=STAFF).status_code == 201
    r = client.post("/api/courses", json={"id": "cg101", "name": "Graphics"}, headers=STAFF)
    assert r.status_code == 409
    assert r.json() == one("there is a course 'cg101' already", "id")


def test_error_bodies_an_unknown_course_is_404_at_course(client):
    r = client.get("/api/courses/nope", headers=STAFF)
    assert r.status_code == 404
    assert r.json() == one("no course with id 'nope'", "course")


def test_error_bodies_an_upload_that_is_not_multipart_is_415(client):
    r = client.post("/api/grade/upload", content=b"{}", headers={"Content-Type": "application/json", **STAFF})
    assert r.status_code == 415
    assert r.json() == one("expected a multipart/form-data body (parts: assignment, then class or files)")


def test_error_bodies_a_wrong_platform_is_422_at_its_field(client):
    body = {"issuer": "http://lms.example", "client_id": "c", "auth_url": "https://lms.example/auth",
            "token_url": "https://lms.example/token", "jwks_url": "https://lms.example/jwks"}  # fmt: skip
    r = client.post("/api/lti/platforms", json=body, headers=STAFF)
    assert r.status_code == 422
    assert [e["path"] for e in r.json()["errors"]] == ["issuer"]


def test_error_bodies_too_many_refused_tokens_is_429_with_retry_after(tmp_path):
    with api_client(tmp_path, instructor_token=INSTRUCTOR, token=None, max_auth_failures=2) as c:
        wrong = bearer("x" * 32)
        for _ in range(2):
            assert c.get("/api/grade/runs", headers=wrong).status_code == 401
        r = c.get("/api/grade/runs", headers=wrong)
        assert r.status_code == 429
        assert int(r.headers["retry-after"]) > 0
        assert r.json()["errors"][0]["path"] == "Authorization"
        assert "TRACER_MAX_AUTH_FAILURES" in r.json()["errors"][0]["message"]
