"""Assignments survive their server (server/course/, server/grading/): `python -m server` on loopback is
killed (SIGKILL) with a burst of submissions half graded, and started again on its data directory; every
submission acknowledged before the kill is graded exactly once: one row in its version's grading run, one
render job, the example's grade. Two submissions are also made to look as if the server had died between
acknowledging them and handing them to their run (their rows' `handed` cleared while it is down): the new
server hands them again, and they are still graded once."""

from __future__ import annotations

import signal
import sqlite3
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import INSTRUCTOR, Server, api_client, bearer, wait_for
from tests.support.assignments_restart import EXAMPLE, slow_alice, spec

SLOW = 8  # students submitting alice's scene at 64 spp and 16 light samples (~0.3 s each to render)


def statuses(server: Server, aid: str) -> dict[str, dict]:
    r = server.client.get(f"/api/assignments/{aid}/submissions", headers=bearer(INSTRUCTOR))
    assert r.status_code == 200, r.text
    return {s["id"]: s for s in r.json()["submissions"]}


def test_assignments_a_killed_server_grades_every_submission_once_when_started_again(tmp_path):
    data = tmp_path / "data"
    env = {"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    server = Server(data, workers=1, env=env).start()
    try:
        deadline = (datetime.now(UTC) + timedelta(days=1)).isoformat()
        r = server.client.post("/api/assignments", json={"spec": spec(), "deadline": deadline},
                               headers=bearer(INSTRUCTOR))  # fmt: skip
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        text = "id,name,email\n" + "".join(f"s{i},Student {i},\n" for i in range(SLOW))
        r = server.client.post(f"/api/assignments/{aid}/roster", content=text,
                               headers={**bearer(INSTRUCTOR), "Content-Type": "text/csv"})  # fmt: skip
        tokens = [s["token"] for s in r.json()["students"]]
        sids = []
        for tok in tokens:
            r = server.client.post(f"/api/assignments/{aid}/submissions", json={"scene": slow_alice()},
                                   headers=bearer(tok))  # fmt: skip
            assert r.status_code == 202 and r.json()["status"] == "queued", r.text
            sids.append(r.json()["id"])

        def mid_burst():
            s = statuses(server, aid)
            graded = sum(x["status"] == "graded" for x in s.values())
            return 1 <= graded <= SLOW - 3 and s

        before = wait_for(mid_burst, 240, "the burst half graded", interval=0.1)
        server.stop(signal.SIGKILL)
        waiting = [sid for sid in sids if before[sid]["status"] != "graded"][:2]
        db = sqlite3.connect(data / "jobs.sqlite3")
        db.executemany("UPDATE course_submissions SET handed = 0 WHERE id = ?", [(s,) for s in waiting])
        db.commit()
        db.close()

        server = Server(data, workers=1, env=env).start()
        done = wait_for(lambda: all((s := statuses(server, aid))[x]["status"] == "graded" for x in sids) and s, 300,
                        "every submission graded", interval=0.2)  # fmt: skip
        assert {(done[x]["score"], done[x]["max_score"]) for x in sids} == {(13.0, 13.0)}
        assert "course: 2 accepted submission(s) handed to their grading runs" in server.log_path.read_text()
    finally:
        server.stop()
    db = sqlite3.connect(data / "jobs.sqlite3")
    try:
        run_id = db.execute("SELECT run_id FROM course_versions WHERE assignment_id = ?", (aid,)).fetchone()[0]
        items = db.execute("SELECT student, COUNT(*) FROM grading_items WHERE run_id = ? GROUP BY student", (run_id,))
        assert dict(items.fetchall()) == {"reference": 1, **{sid: 1 for sid in sids}}
        jobs = dict(db.execute("SELECT name, COUNT(*) FROM jobs WHERE name LIKE 'grading: %' GROUP BY name"))
        assert {sid: jobs.get(f"grading: {sid}") for sid in sids} == {sid: 1 for sid in sids}  # rendered once each
    finally:
        db.close()


def test_assignments_an_app_stopped_mid_grading_goes_on_when_started_again(tmp_path):
    """The app stopped (its lifespan ends: the grading runs stop where their rows say) with submissions
    queued and being graded, then started again on the same data directory: each graded once."""
    data = tmp_path / "data"
    settings = {"instructor_token": INSTRUCTOR, "token": INSTRUCTOR}
    with api_client(data, workers=1, **settings) as client:
        r = client.post("/api/assignments", json={"spec": spec(), "deadline": "2100-01-01T00:00:00Z"})
        aid = r.json()["id"]
        r = client.post(f"/api/assignments/{aid}/roster", content="id,name,email\na,A,\nb,B,\nc,C,\n",
                        headers={"Content-Type": "text/csv"})  # fmt: skip
        sids = [client.post(f"/api/assignments/{aid}/submissions", json={"scene": slow_alice()},
                            headers=bearer(s["token"])).json()["id"] for s in r.json()["students"]]  # fmt: skip
        first = statuses_in(client, aid)
    assert any(s["status"] != "graded" for s in first.values())  # stopped before the end
    with api_client(data, workers=1, **settings) as client:
        done = wait_for(lambda: all((s := statuses_in(client, aid))[x]["status"] == "graded" for x in sids) and s,
                        240, "every submission graded", interval=0.2)  # fmt: skip
        assert {(done[x]["score"], done[x]["max_score"]) for x in sids} == {(13.0, 13.0)}
        jobs = [j["name"] for j in client.app.state.store.list_jobs(limit=100)[0]]
        assert sorted(n for n in jobs if n in {f"grading: {x}" for x in sids}) == sorted(f"grading: {x}" for x in sids)


def statuses_in(client, aid: str) -> dict[str, dict]:
    return {s["id"]: s for s in client.get(f"/api/assignments/{aid}/submissions").json()["submissions"]}


@pytest.fixture(scope="module")
def redis_server(tmp_path_factory):
    from tests.support.queue import RedisServer

    with RedisServer(tmp_path_factory.mktemp("redis") / "redis.log") as r:
        yield r


def test_assignments_on_the_redis_backend(redis_server, tmp_path):
    """The same course with the renders on a worker host through Redis (the API renders nothing): a scene
    and an image graded as the example class is, and the grades exported."""
    import base64

    from tests.support.queue import Api, Process, worker_argv

    api = Api(tmp_path / "data", redis_server.url).start()  # on loopback without a token: the instructor is anyone
    host = Process(worker_argv(redis_server.url, "host-a", threads=2), tmp_path / "host-a.log").start()
    try:
        api.wait_hosts(1)
        c = api.client
        r = c.post("/api/assignments", json={"spec": spec(), "deadline": "2100-01-01T00:00:00Z"})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        r = c.post(f"/api/assignments/{aid}/roster", content="id,name,email\na,A,\ng,G,\n",
                   headers={"Content-Type": "text/csv"})  # fmt: skip
        tok = {s["id"]: s["token"] for s in r.json()["students"]}
        png = base64.b64encode((EXAMPLE / "class" / "grace.png").read_bytes()).decode()
        subs = {
            "a": c.post(f"/api/assignments/{aid}/submissions", json={"scene": slow_alice()}, headers=bearer(tok["a"])),
            "g": c.post(f"/api/assignments/{aid}/submissions", json={"image": png, "format": "png"},
                        headers=bearer(tok["g"])),
        }  # fmt: skip
        assert all(r.status_code == 202 for r in subs.values()), [r.text for r in subs.values()]

        def graded():
            got = {k: c.get(r.headers["location"], headers=bearer(tok[k])).json() for k, r in subs.items()}
            return all(g["status"] == "graded" for g in got.values()) and got

        got = wait_for(graded, 300, "both graded on the worker host", interval=0.2)
        assert {k: (g["score"], g["max_score"]) for k, g in got.items()} == {"a": (13.0, 13.0), "g": (7.0, 7.0)}
        assert c.get(f"/api/assignments/{aid}/grades.csv").text.splitlines()[1:] == ["a,A,13,13,false,1",
                                                                                     "g,G,7,7,false,1"]  # fmt: skip
        assert "job " in host.log_path.read_text()  # the host rendered them
    finally:
        host.stop()
        api.stop()
