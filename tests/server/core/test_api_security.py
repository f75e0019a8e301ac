"""Who may do what (server/core/security.py): each student's jobs are theirs alone, the instructor's routes need
the instructor, the Host header is checked, and every answer has the security headers.

`client` (conftest.py) is a student of a server with an instructor token; the other students here are
other tokens sent by the same TestClient. The loopback server without an instructor token, the server
open to others without one, and the host names get apps of their own.
"""

from __future__ import annotations

import base64
import hashlib
import logging
import re
from contextlib import contextmanager

import pytest

from server.core.security import host_name, loopback_only, served_hosts, token_hash
from server.core.settings import Settings
from tests.support.api import (
    INSTRUCTOR,
    api_client,
    bearer,
    long_scene,
    student_token,
    submit,
    tiny_scene,
    wait_finished,
    wait_for,
    wait_status,
)
from tests.support.scene import scene_dict, small

TEACHER = bearer(INSTRUCTOR)
JOB_ROUTES = ["", "/image", "/image?format=exr", "/scene", "/events", "/aov", "/aov/rays", "/radiosity"]


@contextmanager
def anonymous(client):
    """Requests of `client` without its token (no Authorization header at all)."""
    saved = client.headers.pop("authorization", None)
    try:
        yield client
    finally:
        if saved is not None:
            client.headers["authorization"] = saved


def not_found(job_id: str) -> dict:
    """The answer for a job id that does not exist (the very same for someone else's job)."""
    return {"errors": [{"path": "id", "message": f"no job with id '{job_id}'"}]}


def radiosity_scene() -> dict:
    return small(scene_dict("cornell_radiosity"), 16, 16, sampler={"type": "jittered", "spp": 1})


# -- each student's jobs are theirs ----------------------------------------------------------------


def wait_status_as(client, job_id: str, headers: dict, statuses=("done", "failed", "cancelled")) -> dict:
    """The job, read with `headers`, once its status is one of `statuses`."""

    def ended():
        r = client.get(f"/api/jobs/{job_id}", headers=headers)
        assert r.status_code == 200, r.text
        return r.json() if r.json()["status"] in statuses else None

    return wait_for(ended, 120, f"job {job_id} in {statuses}")


def test_api_security_a_submission_without_a_token_gets_one_that_owns_the_job(client):
    with anonymous(client):
        r = client.post("/api/jobs", json={"scene": tiny_scene()})
        assert r.status_code == 202, r.text
        issued, job_id = r.json()["token"], r.json()["id"]
        assert re.fullmatch(r"[A-Za-z0-9_-]{43}", issued)  # secrets.token_urlsafe(32)
        assert client.get(f"/api/jobs/{job_id}").json() == not_found(job_id)  # without it: not theirs
        again = client.post("/api/jobs", json={"scene": tiny_scene()}).json()
        assert again["token"] != issued  # every submission without a token is a new owner
    assert client.get(f"/api/jobs/{job_id}").json() == not_found(job_id)  # another student's token: neither
    owner = bearer(issued)
    assert wait_status_as(client, job_id, owner)["status"] == "done"
    assert client.get(f"/api/jobs/{job_id}/image", headers=owner).headers["content-type"] == "image/png"
    listed = client.get("/api/jobs", headers=owner).json()
    assert [j["id"] for j in listed["jobs"]] == [job_id]
    assert listed["count"] == 1
    # a submission with the token keeps to it: no new token
    second = client.post("/api/jobs", json={"scene": tiny_scene()}, headers=owner)
    assert second.status_code == 202
    assert second.json()["token"] is None
    wait_status_as(client, second.json()["id"], owner)
    assert client.get("/api/jobs", headers=owner).json()["count"] == 2
    # the store keeps the token's hash, never the token
    row = client.app.state.store.get(job_id)
    assert row["owner"] == token_hash(issued) == hashlib.sha256(issued.encode()).hexdigest()
    assert issued not in str(row)
    wait_status_as(client, again["id"], bearer(again["token"]))


def test_api_security_another_student_gets_the_404_of_an_unknown_id_on_every_route(client):
    """Student B cannot read, stream, download, see the AOVs or radiosity of, or cancel student A's job:
    every answer is byte for byte the one for an id that does not exist."""
    a = client  # the client's own token is student A
    b = bearer(student_token())
    done = submit(a, radiosity_scene())["id"]
    wait_status(a, done, {"done"})
    for route in JOB_ROUTES:  # A's own: all there
        assert a.get(f"/api/jobs/{done}{route}").status_code == 200, route
    unknown = "A" * 22
    for route in JOB_ROUTES:
        theirs = a.get(f"/api/jobs/{done}{route}", headers=b)
        nothing = a.get(f"/api/jobs/{unknown}{route}", headers=b)
        assert theirs.status_code == nothing.status_code == 404, route
        assert theirs.json() == not_found(done) and nothing.json() == not_found(unknown), route
        assert theirs.content.replace(done.encode(), unknown.encode()) == nothing.content, route
        assert {k: v for k, v in theirs.headers.items() if k != "content-length"} == {
            k: v for k, v in nothing.headers.items() if k != "content-length"
        }, route
    running = submit(a, long_scene())["id"]
    wait_status(a, running, {"running"})
    r = a.delete(f"/api/jobs/{running}", headers=b)
    assert r.status_code == 404 and r.json() == not_found(running)
    assert a.get(f"/api/jobs/{running}").json()["status"] == "running"  # B's cancel did nothing
    assert a.delete(f"/api/jobs/{running}").status_code == 202  # A's does
    wait_finished(a, running)
    # lists: each student sees their own jobs only; no token, no jobs
    assert done in {j["id"] for j in a.get("/api/jobs", params={"limit": 1000}).json()["jobs"]}
    assert a.get("/api/jobs", headers=b).json() == {"jobs": [], "count": 0}
    with anonymous(a):
        assert a.get("/api/jobs").json() == {"jobs": [], "count": 0}
        assert a.get(f"/api/jobs/{done}").json() == not_found(done)


def test_api_security_health_names_a_worker_s_job_to_its_owner_only(client):
    running = submit(client, long_scene())["id"]
    try:
        wait_status(client, running, {"running"})

        def jobs(headers=None):
            return [w["job"] for w in client.get("/api/health", headers=headers).json()["workers"]]

        assert jobs() == [running] and jobs(TEACHER) == [running]
        assert jobs(bearer(student_token())) == [None]
    finally:
        client.delete(f"/api/jobs/{running}")
        wait_finished(client, running)


def test_api_security_the_instructor_sees_every_job_and_a_student_cannot_list_them(client):
    a_job = submit(client, tiny_scene())["id"]
    other = bearer(student_token())
    b_job = client.post("/api/jobs", json={"scene": tiny_scene()}, headers=other).json()["id"]
    wait_status(client, a_job, {"done"})
    wait_status_as(client, b_job, other)
    every = client.get("/api/jobs", params={"limit": 1000}, headers=TEACHER).json()
    assert {a_job, b_job} <= {j["id"] for j in every["jobs"]}
    assert client.get("/api/jobs", params={"limit": 1000, "scope": "all"}, headers=TEACHER).json() == every
    assert client.get("/api/jobs", params={"scope": "mine"}, headers=TEACHER).json()["count"] == 0
    for job_id in (a_job, b_job):
        assert client.get(f"/api/jobs/{job_id}", headers=TEACHER).status_code == 200
        assert client.get(f"/api/jobs/{job_id}/image", headers=TEACHER).status_code == 200
    r = client.get("/api/jobs", params={"scope": "all"})  # a student asking for every job
    assert r.status_code == 401
    assert r.headers["www-authenticate"].startswith("Bearer")
    assert r.json()["errors"][0]["path"] == "Authorization"
    assert "instructor" in r.json()["errors"][0]["message"]
    assert [j["id"] for j in client.get("/api/jobs", params={"scope": "mine"}, headers=other).json()["jobs"]] == [b_job]


def test_api_security_jobs_without_an_owner_are_the_instructor_s(client_without_workers):
    """Grading renders and rows from before owners have no owner: the instructor's, never a student's (no worker:
    the row stays queued while it is listed; a worker of its own took it at its next look, half a second)."""
    client = client_without_workers
    store = client.app.state.store
    row = store.create(
        '{"name": "grading: erin"}', name="grading: erin", width=4, height=4, spp=1, priority=0, warnings=[],
        max_seconds=60, max_queued=1000, samples_total=16,
    )  # fmt: skip
    try:
        assert row["owner"] is None
        assert client.get(f"/api/jobs/{row['id']}").json() == not_found(row["id"])
        assert row["id"] not in {j["id"] for j in client.get("/api/jobs", params={"limit": 1000}).json()["jobs"]}
        assert client.get(f"/api/jobs/{row['id']}", headers=TEACHER).json()["name"] == "grading: erin"
        listed = client.get("/api/jobs", params={"status": "queued"}, headers=TEACHER).json()["jobs"]
        assert row["id"] in {j["id"] for j in listed}
    finally:
        store.cancel(row["id"])


def test_api_security_grading_renders_belong_to_no_student(tmp_path):
    """The renders a grading run queues are no student's: a student lists none and reads none."""
    with api_client(tmp_path / "data", workers=0, instructor_token=INSTRUCTOR) as c:
        example = c.get("/api/grade/example", headers=TEACHER).json()
        r = c.post(
            "/api/grade",
            json={"assignment": example["assignment"], "submissions": example["submissions"][:1]},
            headers=TEACHER,
        )
        assert r.status_code == 202, r.text

        def grading_jobs():
            jobs = c.get("/api/jobs", params={"status": "queued"}, headers=TEACHER).json()["jobs"]
            return [j for j in jobs if (j["name"] or "").startswith("grading")]

        queued = wait_for(grading_jobs, 60, "the grading run's renders")
        assert c.get("/api/jobs").json() == {"jobs": [], "count": 0}
        for j in queued:
            assert c.get(f"/api/jobs/{j['id']}").json() == not_found(j["id"])
            assert c.delete(f"/api/jobs/{j['id']}").json() == not_found(j["id"])


@pytest.mark.parametrize(
    "header",
    [
        "Basic dXNlcjpwYXNz",  # another scheme
        "Bearer",  # no token
        "Bearer ",
        "Bearer short",  # under 16 characters
        "Bearer has spaces in the token",
        "Bearer " + "x" * 513,  # over 512
        "Bearer abcdefghijklmnop\x7f",
        "token abcdefghijklmnopqrstuvwxyz",
    ],
)
def test_api_security_a_malformed_authorization_header_is_401(client, header):
    job_id = "A" * 22
    for method, path in (
        ("POST", "/api/jobs"),
        ("GET", "/api/jobs"),
        ("GET", f"/api/jobs/{job_id}"),
        ("GET", f"/api/jobs/{job_id}/events"),
        ("DELETE", f"/api/jobs/{job_id}"),
        ("GET", "/api/grade/schema"),
    ):
        body = {"scene": tiny_scene()} if method == "POST" else None
        r = client.request(method, path, json=body, headers={"Authorization": header})
        assert r.status_code == 401, (method, path, r.text)
        assert r.headers["www-authenticate"].startswith('Bearer realm="tracer"'), (method, path)
        (error,) = r.json()["errors"]
        assert error["path"] == "Authorization" and "Bearer <token>" in error["message"], error


# -- the instructor --------------------------------------------------------------------------------


def test_api_security_grading_needs_the_instructor_s_token(client):
    for headers in ({}, bearer(student_token())):
        with anonymous(client):
            for method, path in (
                ("GET", "/api/grade/example"),
                ("GET", "/api/grade/schema"),
                ("POST", "/api/grade/students"),
                ("POST", "/api/grade"),
                ("POST", "/api/grade/upload"),
                ("GET", "/api/grade/nosuchrun"),
                ("GET", "/api/grade/nosuchrun/summary.csv"),
                ("GET", "/api/grade/nosuchrun/students/erin/report.json"),
            ):
                r = client.request(method, path, json={} if method == "POST" else None, headers=headers)
                assert r.status_code == 401, (method, path, r.text)
                assert r.headers["www-authenticate"].startswith("Bearer"), (method, path)
                assert "instructor" in r.json()["errors"][0]["message"], (method, path)
    assert client.get("/api/grade/schema", headers=TEACHER).status_code == 200
    r = client.post("/api/grade/students", json={"files": ["Zoë O'Brien.json"]}, headers=TEACHER)
    assert r.json() == {"students": ["Zoë_O_Brien"]}
    # the instructor's token is also a student's: their jobs are theirs
    own = client.post("/api/jobs", json={"scene": tiny_scene()}, headers=TEACHER).json()
    assert own["token"] is None
    wait_status_as(client, own["id"], TEACHER)
    assert client.get(f"/api/jobs/{own['id']}").status_code == 404


def test_api_security_loopback_without_an_instructor_token_works_as_before(tmp_path):
    """One person on their own machine: no token needed for anything, every job readable by anyone."""
    with api_client(tmp_path / "data", workers=1, token=None) as c:
        mine = bearer(student_token())
        job_id = c.post("/api/jobs", json={"scene": tiny_scene()}, headers=mine).json()["id"]
        wait_status(c, job_id, {"done"})  # without a token: as before
        for route in JOB_ROUTES[:6]:
            assert c.get(f"/api/jobs/{job_id}{route}").status_code == 200, route
        assert [j["id"] for j in c.get("/api/jobs").json()["jobs"]] == [job_id]
        assert c.get("/api/jobs", params={"scope": "all"}).json()["count"] == 1
        assert c.get("/api/grade/schema").status_code == 200
        assert c.get("/api/grade/example").status_code == 200
        anon = c.post("/api/jobs", json={"scene": long_scene()}).json()
        assert anon["token"]  # a token is still issued, for when the server is shared
        wait_status(c, anon["id"], {"running"})
        assert c.delete(f"/api/jobs/{anon['id']}").status_code == 202
        wait_finished(c, anon["id"])


def test_api_security_a_server_open_to_others_without_an_instructor_token_refuses_grading_and_warns(tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="server")
    with api_client(tmp_path / "data", workers=0, host="10.1.2.3") as c:
        assert any("without TRACER_INSTRUCTOR_TOKEN" in r.getMessage() for r in caplog.records)
        r = c.get("/api/grade/schema")
        assert r.status_code == 403
        assert "TRACER_INSTRUCTOR_TOKEN" in r.json()["errors"][0]["message"]
        assert c.get("/api/jobs", params={"scope": "all"}).status_code == 401
        job_id = c.post("/api/jobs", json={"scene": tiny_scene()}).json()["id"]
        assert c.get(f"/api/jobs/{job_id}").status_code == 200
        assert c.get(f"/api/jobs/{job_id}", headers=bearer(student_token())).json() == not_found(job_id)
        c.delete(f"/api/jobs/{job_id}")


def test_api_security_the_instructor_token_setting_is_checked():
    assert Settings(instructor_token="").instructor_token is None  # an empty variable: unset
    assert Settings(instructor_token=INSTRUCTOR).instructor_token.get_secret_value() == INSTRUCTOR
    for bad in ("short", "has spaces in it, too long", "ü" * 20):
        with pytest.raises(ValueError, match="instructor token must be 16 to 512"):
            Settings(instructor_token=bad)
    assert INSTRUCTOR not in repr(Settings(instructor_token=INSTRUCTOR))


def test_api_security_loopback_is_the_address_the_server_listens_on():
    for host in ("127.0.0.1", "127.0.0.2", "::1", "[::1]", "localhost", "LOCALHOST"):
        assert loopback_only(host), host
    for host in ("0.0.0.0", "::", "10.1.2.3", "192.168.1.5", "render.example.edu", "", "fe80::1"):
        assert not loopback_only(host), host


# -- host names ------------------------------------------------------------------------------------


def test_api_security_a_foreign_host_header_is_400(client):
    for host in ("127.0.0.1", "127.0.0.1:8000", "localhost:8000", "LOCALHOST", "[::1]:8000", "[::1]"):
        assert client.get("/api/health", headers={"Host": host}).status_code == 200, host
    for host in ("attacker.example", "attacker.example:8000", "127.0.0.1.attacker.example", "10.0.0.1", ""):
        r = client.get("/api/health", headers={"Host": host})
        assert r.status_code == 400, host
        (error,) = r.json()["errors"]
        assert error["path"] == "Host" and "TRACER_ALLOWED_HOSTS" in error["message"], error
        assert "not a name this server answers to" in error["message"]
    assert client.get("/", headers={"Host": "attacker.example"}).status_code == 400  # the page too


def test_api_security_served_host_names(tmp_path):
    def served(**kw):
        return served_hosts(Settings(**kw))

    assert served() == {"localhost", "127.0.0.1", "::1"}
    assert served(host="10.1.2.3") == {"localhost", "127.0.0.1", "::1", "10.1.2.3"}
    assert served(host="::1") == {"localhost", "127.0.0.1", "::1"}
    assert served(host="0.0.0.0") is None and served(host="::") is None  # every address, no list: any
    assert served(host="0.0.0.0", allowed_hosts="render.example.edu") == {
        "localhost", "127.0.0.1", "::1", "render.example.edu",
    }  # fmt: skip
    assert served(allowed_hosts="*") is None
    assert host_name("[::1]:8000") == "::1" and host_name("Example.EDU.:80") == "example.edu"
    assert host_name("render.example.edu") == "render.example.edu"
    with api_client(tmp_path / "a", allowed_hosts="render.example.edu, .school.edu") as c:
        for host in ("render.example.edu", "render.example.edu:8000", "school.edu", "a.school.edu", "127.0.0.1"):
            assert c.get("/api/health", headers={"Host": host}).status_code == 200, host
        for host in ("example.edu", "evilschool.edu", "school.edu.evil"):
            assert c.get("/api/health", headers={"Host": host}).status_code == 400, host


def test_api_security_every_address_without_a_list_accepts_any_host_and_warns(tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="server")
    with api_client(tmp_path / "data", host="0.0.0.0", instructor_token=INSTRUCTOR) as c:
        assert c.get("/api/health", headers={"Host": "anything.example"}).status_code == 200
    messages = [r.getMessage() for r in caplog.records]
    assert any("any Host header is accepted" in m for m in messages), messages
    assert not any("without TRACER_INSTRUCTOR_TOKEN" in m for m in messages)


# -- headers ---------------------------------------------------------------------------------------


def test_api_security_headers_on_the_page_its_assets_and_the_api(client):
    for path in ("/", "/index.html", "/js/main.js", "/css/app.css", "/api/health", "/reference/", "/nothing"):
        r = client.get(path)
        assert r.headers["x-content-type-options"] == "nosniff", path
        assert r.headers["x-frame-options"] == "DENY", path
        assert r.headers["referrer-policy"] == "same-origin", path
        policy = dict(p.strip().split(" ", 1) for p in r.headers["content-security-policy"].split(";"))
        assert policy["default-src"] == "'self'" and policy["frame-ancestors"] == "'none'", path
        assert policy["img-src"] == "'self' blob: data:" and "script-src" not in policy, path
    assert client.get("/js/main.js").headers["content-type"].startswith("text/javascript")
    # the page has no inline script or style for the policy to block
    page = client.get("/").text
    assert not re.search(r"<script(?![^>]*\bsrc=)[^>]*>", page) and "<style" not in page and "style=" not in page


def test_api_security_the_api_docs_allow_their_one_inline_script_by_hash(client):
    r = client.get("/docs")
    assert r.status_code == 200
    scripts = re.findall(r"<script>(.*?)</script>", r.text, re.S)
    assert len(scripts) == 1
    assert "SwaggerUIBundle" in scripts[0]
    digest = base64.b64encode(hashlib.sha256(scripts[0].encode()).digest()).decode()
    policy = dict(p.strip().split(" ", 1) for p in r.headers["content-security-policy"].split(";"))
    assert policy["script-src"] == f"'self' 'sha256-{digest}'"
    assert "unsafe-inline" not in policy["script-src"]
    assert policy["frame-ancestors"] == "'none'"
    assert r.headers["x-content-type-options"] == "nosniff"
    assert "token" in client.get("/openapi.json").json()["components"]["securitySchemes"]


# -- other sites -----------------------------------------------------------------------------------

EVIL = "http://evil.example"


@pytest.fixture(scope="module")
def own_machine(tmp_path_factory):
    """A loopback server without an instructor token (everyone is the instructor), no workers."""
    with api_client(tmp_path_factory.mktemp("own-machine"), workers=0, token=None) as c:
        yield c


def test_api_security_a_page_of_another_site_cannot_publish_on_a_loopback_server(own_machine):
    """A page of another origin posted a multipart form that published an assignment on a loopback server without
    an instructor token: now a state-changing request with a foreign Origin, or Sec-Fetch-Site: cross-site, is a
    403 naming the Origin header, before the route reads anything."""
    form = {"spec": ("spec.json", b"{}", "application/json"), "deadline": (None, "2030-01-01T00:00:00Z")}
    r = own_machine.post("/api/assignments", files=form, headers={"Origin": EVIL})
    assert r.status_code == 403, r.text
    [error] = r.json()["errors"]
    assert error["path"] == "Origin" and "'http://evil.example'" in error["message"], error
    r = own_machine.post("/api/assignments", files=form, headers={"Sec-Fetch-Site": "cross-site"})
    assert r.status_code == 403 and r.json()["errors"][0]["path"] == "Origin", r.text
    for method in ("PUT", "PATCH", "DELETE"):
        r = own_machine.request(method, f"/api/jobs/{'0' * 32}", headers={"Origin": "null"})
        assert r.status_code == 403, (method, r.text)
    r = own_machine.post("/api/validate", json={"scene": tiny_scene()}, headers={"Origin": "http://127.0.0.1.evil"})
    assert r.status_code == 403, r.text


def test_api_security_the_server_s_own_page_and_clients_without_a_browser_pass(own_machine):
    """Same origin (scheme and Host, the default port or not), a served host's other port, same-site, and a
    request with neither header (curl) reach the route; GET is never checked; LTI's login and launch, which a
    learning platform posts from its own site, are exempt (they answer their own refusal of a launch without a
    platform or a state, 400, never the cross-site 403)."""
    scene = {"scene": tiny_scene()}
    for headers in (
        {},
        {"Origin": "http://127.0.0.1", "Sec-Fetch-Site": "same-origin"},
        {"Origin": "http://127.0.0.1:80"},
        {"Origin": "http://localhost:5173", "Sec-Fetch-Site": "same-site"},
    ):
        r = own_machine.post("/api/validate", json=scene, headers=headers)
        assert r.status_code == 200, (headers, r.text)
    assert own_machine.get("/api/health", headers={"Origin": EVIL, "Sec-Fetch-Site": "cross-site"}).status_code == 200
    for path in ("/lti/login", "/lti/launch"):
        r = own_machine.post(path, data={"id_token": "x"}, headers={"Origin": EVIL, "Sec-Fetch-Site": "cross-site"})
        assert r.status_code == 400 and "The launch was refused" in r.text, (path, r.text)


def test_api_security_a_foreign_origin_is_refused_on_a_server_with_an_instructor_token(client):
    r = client.delete(f"/api/jobs/{'0' * 32}", headers={**TEACHER, "Origin": EVIL})
    assert r.status_code == 403 and r.json()["errors"][0]["path"] == "Origin", r.text


def test_api_security_no_api_answer_is_kept_in_a_cache(client):
    """Every /api answer says `Cache-Control: no-store`, whatever its route said (a job's token, a student's work,
    an error, an event stream, a scene's preview); the page and its assets may be cached."""
    created = submit(client, tiny_scene())
    assert created["token"] is None
    with anonymous(client):
        issued = client.post("/api/jobs", json={"scene": tiny_scene()})  # a new token in the answer
    assert issued.status_code == 202 and issued.json()["token"], issued.text
    answers = [
        issued,
        client.get(f"/api/jobs/{created['id']}"),
        client.get(f"/api/jobs/{'0' * 22}"),  # 404
        client.get("/api/jobs"),
        client.get("/api/health"),
        client.get("/api/schema"),
        client.get("/api/scenes"),
        client.get("/api/assignments", headers=TEACHER),
    ]
    for r in answers:
        assert r.headers.get("cache-control") == "no-store", (r.request.url, r.status_code, r.headers)
    with client.stream("GET", f"/api/jobs/{created['id']}/events") as r:
        assert r.headers["cache-control"] == "no-store"
    wait_finished(client, created["id"])
    wait_status_as(client, issued.json()["id"], bearer(issued.json()["token"]))
    for path in ("/", "/js/main.js"):
        assert client.get(path).headers.get("cache-control") != "no-store", path


def test_api_security_a_weak_instructor_token_is_refused_off_loopback_and_warned_on_it():
    """An instructor token shorter than 24 characters, or worth fewer than about 96 bits, guards every student's
    grade badly: a server listening beyond loopback refuses to start with it (naming the setting, never the
    token), one on loopback warns at start-up."""
    from server.core.credentials import token_bits
    from server.core.security import start_up_warnings

    for weak in ("abcdefghijklmnop", "x" * 40, "ab" * 20, "0123456789" * 2 + "012"):
        with pytest.raises(ValueError, match="instructor token is too weak for a server listening on 10.1.2.3"):
            Settings(host="10.1.2.3", instructor_token=weak)
        on_loopback = Settings(instructor_token=weak)
        assert any("TRACER_INSTRUCTOR_TOKEN is weak" in w for w in start_up_warnings(on_loopback)), weak
    assert token_bits("abcdefghijklmnopqrstuvwx") > 96 and token_bits("x" * 40) == 0
    for strong in (INSTRUCTOR, student_token()):
        settings = Settings(host="10.1.2.3", instructor_token=strong)
        assert not any("is weak" in w for w in start_up_warnings(settings))


def test_api_security_python_m_server_names_the_weak_token_without_showing_it(tmp_path):
    import os
    import subprocess
    import sys

    from tests.support.scene import ROOT

    env = {**os.environ, "TRACER_INSTRUCTOR_TOKEN": "weak-but-16-chars"}
    argv = [sys.executable, "-m", "server", "--host", "10.1.2.3", "--data-dir", str(tmp_path / "data")]
    r = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "TRACER_INSTRUCTOR_TOKEN: the instructor token is too weak" in r.stderr and "24" in r.stderr, r.stderr
    assert "weak-but-16-chars" not in r.stderr
