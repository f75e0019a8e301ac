"""The course on the Redis backend (server/course/, server/queue/redis/): a real redis-server on loopback, the API
with `--redis` (it renders nothing) and two worker hosts (`python -m server.worker`), as the queue's Redis tests
start them (tests/queue_support.py). The instructor publishes with a feedback policy that never shows the pixel
test (so the score is the instructor's alone), uploads the roster; students submit scenes and an image; what
each sees follows the policy, and grades.csv has a row per roster student. In the middle of a burst a worker
host dies whole (SIGKILL of its process group and of its work horse's, which RQ puts in a session of its own),
and in another burst Redis itself is restarted (its data gone; one submission comes while it is down): every
submission is graded exactly once: one row in its version's grading run, one render job (a lost try runs again
as the same job's next attempt). A killed API is test_api_assignments_restart.py's."""

from __future__ import annotations

import base64
import csv
import io
import json
import os
import signal
import sqlite3

import pytest

from tests.support.api import INSTRUCTOR, bearer, wait_for
from tests.support.assignments_restart import slow_alice, spec
from tests.support.queue import Api, Process, RedisServer, proc_env, worker_argv
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
TEACHER = bearer(INSTRUCTOR)
FEEDBACK = {"tests": {"pixels": "never"}}  # the score, by default the latest of the tests': never, for a student


class Course:
    """Redis, the API and two worker hosts, and one published assignment."""

    def __init__(self, root):
        self.root = root
        self.redis = RedisServer(root / "redis.log").__enter__()
        self.env = proc_env(TRACER_INSTRUCTOR_TOKEN=INSTRUCTOR)
        self.api = Api(root / "data", self.redis.url, env=self.env).start()
        self.hosts = {name: self.host(name) for name in ("host-a", "host-b")}
        self.api.wait_hosts(2)
        body = {"spec": spec(), "deadline": "2100-01-01T00:00:00Z", "feedback": FEEDBACK, "max_submissions": 2,
                "counts": "best"}  # fmt: skip
        r = self.api.client.post("/api/assignments", json=body, headers=TEACHER)
        assert r.status_code == 201, r.text
        self.aid, self.run_id = r.json()["id"], r.json()["run_id"]

    def host(self, name: str) -> Process:
        return Process(worker_argv(self.redis.url, name), self.root / f"{name}.log", self.env).start()

    def roster(self, ids: list[str]) -> dict[str, str]:
        text = "id,name,email\n" + "".join(f"{i},Student {i},\n" for i in ids)
        r = self.api.client.post(f"/api/assignments/{self.aid}/roster", content=text,
                                 headers={**TEACHER, "Content-Type": "text/csv"})  # fmt: skip
        assert r.status_code == 200, r.text
        return {s["id"]: s["token"] for s in r.json()["students"] if s["id"] in ids}

    def submit(self, token: str, body: dict) -> str:
        r = self.api.client.post(f"/api/assignments/{self.aid}/submissions", json=body, headers=bearer(token))
        assert r.status_code == 202 and r.json()["status"] == "queued", r.text
        return r.json()["id"]

    def all(self) -> dict[str, dict]:
        r = self.api.client.get(f"/api/assignments/{self.aid}/submissions", headers=TEACHER)
        assert r.status_code == 200, r.text
        return {s["id"]: s for s in r.json()["submissions"]}

    def graded(self, sids: list[str], timeout: float = 120) -> dict[str, dict]:
        return wait_for(lambda: all((s := self.all())[x]["status"] == "graded" for x in sids) and s, timeout,
                        "every submission graded", interval=0.2)  # fmt: skip

    def once(self, sids: list[str], rendered: list[str]) -> dict[str, int]:
        """One grading row for each submission and one render job for each of `rendered` (the scenes that
        validate; an image needs none of its own); each job's attempts, by submission."""
        db = sqlite3.connect(self.root / "data" / "jobs.sqlite3")
        try:
            marks = ",".join("?" * len(sids))
            rows = dict(db.execute(f"SELECT student, COUNT(*) FROM grading_items WHERE run_id = ? AND student IN "
                                   f"({marks}) GROUP BY student", (self.run_id, *sids)).fetchall())  # fmt: skip
            names = [f"grading: {s}" for s in sids]
            jobs = db.execute(f"SELECT name, attempts FROM jobs WHERE name IN ({marks})", names).fetchall()
        finally:
            db.close()
        assert rows == {sid: 1 for sid in sids}
        assert sorted(n for n, _ in jobs) == sorted(f"grading: {s}" for s in rendered)  # one render job each
        return {n.removeprefix("grading: "): a for n, a in jobs}

    def job_of(self, sid: str) -> str | None:
        """The render job of a submission, once its grading run has made it (its row there)."""
        db = sqlite3.connect(self.root / "data" / "jobs.sqlite3")
        try:
            row = db.execute("SELECT job_id FROM grading_items WHERE run_id = ? AND student = ?",
                             (self.run_id, sid)).fetchone()  # fmt: skip
        finally:
            db.close()
        return row[0] if row else None

    def running(self, sid: str) -> str | None:
        """The worker host rendering this submission's job now."""
        job_id = self.job_of(sid)
        if job_id is None:
            return None
        job = self.api.client.get(f"/api/jobs/{job_id}", headers=TEACHER).json()
        started = job["status"] == "running" and job["progress"]["passes_done"] >= 1  # well into it
        return job["tries"][-1]["worker"] if started and job["tries"] else None

    def close(self) -> None:
        for h in self.hosts.values():
            h.stop()
        self.api.stop()
        self.redis.__exit__(None, None, None)


@pytest.fixture(scope="module")
def course(tmp_path_factory):
    c = Course(tmp_path_factory.mktemp("course-redis"))
    try:
        yield c
    finally:
        c.close()


def descendants(pid: int) -> list[int]:
    parents = {}
    for stat in os.scandir("/proc"):
        if stat.name.isdigit():
            try:
                with open(f"/proc/{stat.name}/stat") as f:
                    parents[int(stat.name)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, parent in parents.items() if parent == p]
        out += kids
        todo += kids
    return out


def slower_alice() -> dict:
    """Alice's scene with 150 tiny spheres far behind the camera: the same picture, a render of seconds (the
    spheres are tested by every ray), so a host can die in the middle of it; it fails 'a small scene' (12 / 13)."""
    scene = slow_alice()
    material = scene["objects"][0]["material"]
    scene["objects"] += [{"type": "sphere", "center": [k % 15 - 7, k // 15, 60.0], "radius": 0.001,
                          "material": material} for k in range(150)]  # fmt: skip
    return scene


def test_assignments_redis_a_class_graded_once_through_a_dead_worker_host(course):
    tokens = course.roster([f"s{i}" for i in range(6)] + ["absent"])
    png = base64.b64encode((EXAMPLE / "class" / "grace.png").read_bytes()).decode()
    sids = {"s0": course.submit(tokens["s0"], {"scene": slower_alice()})}
    sids.update({f"s{i}": course.submit(tokens[f"s{i}"], {"scene": slow_alice()}) for i in range(1, 5)})
    sids["s5"] = course.submit(tokens["s5"], {"image": png, "format": "png"})

    name = wait_for(lambda: course.running(sids["s0"]), 120, "a host rendering the slow submission", interval=0.05)
    victim = course.hosts[name]
    horses = descendants(victim.pid)
    victim.stop(signal.SIGKILL)  # its process group
    for pid in horses:  # and its work horse, in a session of its own
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert any(s["status"] != "graded" for s in course.all().values() if s["id"] in sids.values())  # mid-burst

    done = course.graded(list(sids.values()))
    mine = {k: course.api.client.get(f"/api/assignments/{course.aid}/submissions/{sid}", headers=bearer(tokens[k]))
            for k, sid in sids.items()}  # fmt: skip
    assert all(r.status_code == 200 for r in mine.values())
    for k, sid in sids.items():
        teacher, student = done[sid], mine[k].json()
        assert (teacher["score"], teacher["max_score"]) == {"s0": (12.0, 13.0), "s5": (7.0, 7.0)}.get(k, (13.0, 13.0))
        assert student["status"] == "graded"
        assert student["score"] is None  # the pixel test is never shown
        pixels = [t for t in student["feedback"]["tests"] if t["test"] == "pixels"]
        assert pixels == [{"name": pixels[0]["name"], "test": "pixels", "max_score": 2, "shown": "never",
                           "hidden": "shown never"}]  # fmt: skip
        assert all("score" in t for t in student["feedback"]["tests"] if t["test"] != "pixels")
        assert "metrics" not in student["feedback"] and "pixels" in json.dumps(teacher["feedback"])
    attempts = course.once(list(sids.values()), [sids[f"s{i}"] for i in range(5)])
    assert attempts[sids["s0"]] == 2, attempts  # the dead host's try ran again, on the other host

    r = course.api.client.get(f"/api/assignments/{course.aid}/grades.csv", headers=TEACHER)
    rows = list(csv.DictReader(io.StringIO(r.text)))
    got = {x["id"]: (x["score"], x["max_score"], x["late"], x["submissions"]) for x in rows}
    assert got == {"s0": ("12", "13", "false", "1"), **{f"s{i}": ("13", "13", "false", "1") for i in range(1, 5)},
                   "s5": ("7", "7", "false", "1"), "absent": ("", "", "", "0")}  # fmt: skip
    course.hosts[name] = course.host(name)  # back, for the next test
    course.api.wait_hosts(2)


def test_assignments_redis_a_restarted_redis_loses_no_submission(course):
    """Redis is stopped with a burst half graded and started again empty on its port; a submission comes
    while it is down (acknowledged: its row is in SQLite) and its grading run makes its render job then (the
    job waits in the job store). The API queues the lost tries and that job once Redis is back."""
    tokens = course.roster([f"r{i}" for i in range(6)])
    sids = [course.submit(tokens[f"r{i}"], {"scene": slow_alice()}) for i in range(5)]
    wait_for(lambda: 1 <= sum(course.all()[x]["status"] == "graded" for x in sids) <= 3, 120, "the burst half graded",
             interval=0.05)  # fmt: skip
    port = course.redis.port
    course.redis.__exit__(None, None, None)
    sids.append(course.submit(tokens["r5"], {"scene": slow_alice()}))
    # its render job is made while Redis is away: queued in the job store, it goes out once Redis is back
    wait_for(lambda: course.job_of(sids[-1]), 60, "the render job of the submission made while Redis is down")
    again = RedisServer(course.root / "redis-again.log")
    again.port, again.url = port, course.redis.url  # the same address: the API and the hosts reconnect
    course.redis = again.__enter__()

    done = course.graded(sids, timeout=180)
    assert {(done[x]["score"], done[x]["max_score"]) for x in sids} == {(13.0, 13.0)}
    course.once(sids, sids)
    log = course.api.log_path.read_text()
    assert "Redis lost its data" in log
    assert f"job {course.job_of(sids[-1])}: Redis unreachable" in log  # made while it was away, sent after
