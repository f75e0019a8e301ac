"""A student cannot take the workers (issue #32, item 1): the server picks a render's lane from its own estimate
and a caller may only move a job down; a priority above 0 is the instructor's; a token has at most
TRACER_MAX_ACTIVE_JOBS_PER_TOKEN renders waiting or running. The same on both queue backends: the embedded one
and Redis (a real redis-server), each an app without workers, so that every job stays where the API put it."""

from __future__ import annotations

import pytest

from tests.support.api import INSTRUCTOR, api_client, bearer, student_token, tiny_scene
from tests.support.queue import RedisServer
from tests.support.scene import scene_dict, small

TEACHER = bearer(INSTRUCTOR)


def long_render() -> dict:
    """Estimated at more than a second (TRACER_INTERACTIVE_SECONDS is 1 here): a batch render by its estimate."""
    return small(scene_dict("whitted"), 128, 96, sampler={"type": "jittered", "spp": 4096})


@pytest.fixture(scope="module", params=["embedded", "redis"])
def app(request, tmp_path_factory):
    data = tmp_path_factory.mktemp(f"fair-share-{request.param}")
    settings = dict(instructor_token=INSTRUCTOR, interactive_seconds=1.0, max_active_jobs_per_token=3)
    if request.param == "embedded":
        with api_client(data / "data", workers=0, token=None, **settings) as c:
            yield c
    else:
        with (
            RedisServer(data / "redis.log") as redis,
            api_client(data / "data", workers=0, token=None, redis_url=redis.url, **settings) as c,
        ):
            yield c


def post(app, token: str, scene: dict, **body):
    return app.post("/api/jobs", json={"scene": scene, **body}, headers=bearer(token))


def cancel_all(app, token: str) -> None:
    for j in app.get("/api/jobs", params={"status": "queued"}, headers=bearer(token)).json()["jobs"]:
        app.delete(f"/api/jobs/{j['id']}", headers=bearer(token))


def test_fair_share_a_student_cannot_move_a_long_render_up_or_ahead(app):
    """`"lane": "interactive", "priority": 100` from a roster token held both workers with 555 s renders: now the
    long render goes to the batch lane at priority 0, each lowered value with a warning naming its field; the
    instructor's request is kept as it is; moving a quick job down to the batch lane is anyone's."""
    me = student_token()
    r = post(app, me, long_render(), lane="interactive", priority=100)
    assert r.status_code == 202, r.text
    job = r.json()
    assert job["estimate"] > 1.0
    assert job["lane"] == "batch"
    assert job["priority"] == 0
    warned = {w["path"]: w["message"] for w in job["warnings"]}
    assert "instructor" in warned["priority"]
    assert "100 was lowered to 0" in warned["priority"]
    assert "batch lane" in warned["lane"]
    assert "TRACER_INTERACTIVE_SECONDS" in warned["lane"]
    r = post(app, me, tiny_scene(), priority=-5)
    assert r.status_code == 202
    assert r.json()["priority"] == -5
    assert r.json()["lane"] == "interactive"  # down: fine
    r = post(app, me, tiny_scene(), lane="batch")
    assert r.status_code == 202
    assert r.json()["lane"] == "batch"
    assert r.json()["warnings"] == []  # down: fine
    staff = app.post(
        "/api/jobs", json={"scene": long_render(), "lane": "interactive", "priority": 100}, headers=TEACHER
    )
    assert staff.status_code == 202, staff.text
    assert staff.json()["lane"] == "interactive"
    assert staff.json()["priority"] == 100
    assert staff.json()["warnings"] == []
    cancel_all(app, me)
    app.delete(f"/api/jobs/{staff.json()['id']}", headers=TEACHER)


def test_fair_share_a_token_has_so_many_renders_waiting_or_running(app):
    """Three renders waiting or running (the setting, here 3) and the token's next is a 429 naming
    TRACER_MAX_ACTIVE_JOBS_PER_TOKEN with Retry-After; a running render counts too, an ended one does not;
    another student and the instructor are not held by it."""
    me, other = student_token(), student_token()
    ids = [post(app, me, tiny_scene(seed=k)).json()["id"] for k in range(3)]
    r = post(app, me, tiny_scene(seed=9))
    assert r.status_code == 429, r.text
    assert 1 <= int(r.headers["retry-after"]) <= 60
    [error] = r.json()["errors"]
    assert "TRACER_MAX_ACTIVE_JOBS_PER_TOKEN" in error["message"] and "3 renders" in error["message"], error
    assert post(app, other, tiny_scene()).status_code == 202  # another token has its own share
    assert app.post("/api/jobs", json={"scene": tiny_scene()}, headers=TEACHER).status_code == 202  # staff: none
    store = app.app.state.store
    assert store.claim(4242) is not None  # one of the waiting renders now runs: it still counts
    assert post(app, me, tiny_scene(seed=9)).status_code == 429
    assert app.delete(f"/api/jobs/{ids[2]}", headers=bearer(me)).status_code in (200, 202)
    r = post(app, me, tiny_scene(seed=9))
    assert r.status_code == 202, r.text
    for token in (me, other, INSTRUCTOR):
        cancel_all(app, token)
    for j in app.get("/api/jobs", params={"status": "running"}, headers=TEACHER).json()["jobs"]:
        app.delete(f"/api/jobs/{j['id']}", headers=TEACHER)
