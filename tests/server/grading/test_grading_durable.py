"""Durable grading runs (server/grading/store.py, server/grading/run.py): a run is rows in SQLite, resumed
by a restarted server with the renders that were done kept, on both queue backends; each student's work
runs in grading processes (tracer/grading/tasks.py), the same reports as grading in process.

The restarts are real: `python -m server` killed (SIGKILL) in the middle of a class and started again on
its data directory. The class is made slow enough to be caught mid-run: copies of alice at the
assignment's most samples (64 spp, 16 light samples), plus carol (invalid) and grace (her own PNG)."""

from __future__ import annotations

import copy
import io
import json
import multiprocessing as mp
import os
import re
import signal
import sqlite3
import zipfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from tests.support.api import Server, api_client, pid_alive, wait_for
from tests.support.scene import ROOT
from tracer.grading import Grader, InlineRenderer, RenderJob, collect, load_assignment, tasks
from tracer.scene import Limits

EXAMPLE = ROOT / "scenes" / "grading"
CLASS = EXAMPLE / "class"
SLOW = 12  # copies of alice at 64 spp and 16 light samples (~0.3 s each on this machine's two cores)


def assignment_text() -> str:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return json.dumps(a)


def slow_class() -> bytes:
    """A zip: SLOW correct but slow scenes (s01, s02, ...), carol (invalid) and grace (a correct PNG)."""
    alice = json.loads((CLASS / "alice.json").read_text())
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for i in range(1, SLOW + 1):
            scene = copy.deepcopy(alice)
            scene["sampler"] = {"type": "jittered", "spp": 64}
            scene["render"]["light_samples"] = 16
            z.writestr(f"hw/s{i:02d}.json", json.dumps(scene))
        z.write(CLASS / "carol.json", "hw/carol.json")
        z.write(CLASS / "grace.png", "hw/grace.png")
    return buf.getvalue()


EXAMPLE_GRADES = {  # the example class (every test's points: tests/tracer/grading/test_grading.py)
    "alice": (13.0, "graded"), "bob": (6.0, "graded"), "carol": (0.0, "invalid"), "dave": (13.0, "graded"),
    "erin": (7.0, "graded"), "frank": (0.0, "invalid"), "grace": (7.0, "graded"), "heidi": (1.0, "graded"),
    "ivan": (0.0, "invalid"),
}  # fmt: skip
SLOW_GRADES = {**{f"s{i:02d}": (13.0, "graded") for i in range(1, SLOW + 1)},
               "carol": (0.0, "invalid"), "grace": (7.0, "graded")}  # fmt: skip


def snapshot(data: Path, run_id: str) -> dict:
    """What the database says of a run: each student's job and stage, the class's renders, and the rows
    of those jobs (status, when each ended, tries), read while the server runs or after it died."""
    db = sqlite3.connect(data / "jobs.sqlite3", timeout=30)
    try:
        rows = db.execute("SELECT student, job_id, stage FROM grading_items WHERE run_id = ?", (run_id,))
        items = {r[0]: {"job": r[1], "stage": r[2]} for r in rows}
        rows = db.execute("SELECT key, job_id, status FROM grading_renders WHERE run_id = ?", (run_id,))
        renders = {r[0]: {"job": r[1], "status": r[2]} for r in rows}
        ids = [x["job"] for x in (*items.values(), *renders.values()) if x["job"]]
        jobs = {r[0]: {"status": r[1], "finished_at": r[2], "attempts": r[3], "tries": json.loads(r[4])} for r in
                db.execute(f"SELECT id, status, finished_at, attempts, tries FROM jobs WHERE id IN "
                           f"({','.join('?' * len(ids))})", ids)}  # fmt: skip
        grading_jobs = db.execute("SELECT COUNT(*) FROM jobs WHERE name LIKE 'grading: %'").fetchone()[0]
    finally:
        db.close()
    return {"items": items, "renders": renders, "jobs": jobs, "grading_jobs": grading_jobs}


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid` (its render workers and grading processes)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def upload(client, zip_bytes: bytes) -> dict:
    r = client.post("/api/grade/upload", data={"assignment": assignment_text()},
                    files={"class": ("hw.zip", zip_bytes, "application/zip")})  # fmt: skip
    assert r.status_code == 202, r.text
    return r.json()


def scores(state: dict) -> dict:
    return {x["student"]: (x["score"], x["status"]) for x in state["reports"]}


def caught_mid_run(client, url: str) -> dict:
    """The run's state once a few renders are done and many are not."""
    return wait_for(lambda: 4 <= (s := client.get(url).json())["renders_done"] <= 8 and s, 240, "renders mid-run")


def check_resumed(before: dict, after: dict, state: dict) -> None:
    """Every job the run had queued before the restart is the one it used after: none queued twice, and
    those that had finished were not rendered again (same end, same tries)."""
    done_before = {j for j, row in before["jobs"].items() if row["status"] == "done"}
    assert len(done_before) >= 4, before  # caught with renders done...
    assert any(x["stage"] != "graded" for x in before["items"].values()), before  # ...and the class not graded
    for name, x in before["items"].items():
        if x["job"]:
            assert after["items"][name]["job"] == x["job"], name
    for key, x in before["renders"].items():
        if x["job"]:
            assert after["renders"][key]["job"] == x["job"], key
    for job_id in done_before:
        assert after["jobs"][job_id] == before["jobs"][job_id], job_id  # not rendered again
    assert after["grading_jobs"] == state["renders_total"] == SLOW + 3  # mean, two baselines, the scenes
    assert len(after["jobs"]) == state["renders_total"]
    assert all(x["stage"] == "graded" for x in after["items"].values())


# ------------------------------------------------------------------------- the tasks, in a process


def test_grading_tasks_in_another_process_give_the_in_process_reports(tmp_path):
    """prepare_submission, measure_baseline and grade_metrics take plain data (JSON text, dicts, paths to
    EXR files) in a spawned process and give what Grader.grade gives in process, bit for bit: every test's
    points and words, the metrics, and the pictures."""
    from tracer.rendering.film import write_exr

    text = assignment_text()
    spec, _ = load_assignment(text)
    subs = [s for s in collect(CLASS) if s.student in ("alice", "carol", "dave", "erin", "grace", "heidi")]
    mine = {r.student: r for r in Grader(spec, None, InlineRenderer()).grade(subs)}
    for s in subs:
        (tmp_path / s.student).write_bytes(s.data)
    with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
        prepared = {s.student: pool.submit(tasks.prepare_submission, text, s.student, s.kind, str(tmp_path / s.student),
                                           s.filename).result()["prepared"] for s in subs}  # fmt: skip
        keys = {tuple(p["key"]) for p in prepared.values() if p["key"]}
        ref_jobs = Grader(spec, None).reference_jobs(keys)
        student_jobs = {s: RenderJob(**{**p["job"], "limits": Limits(**p["job"]["limits"])})
                        for s, p in prepared.items() if p["job"]}  # fmt: skip
        rendered = InlineRenderer()([j for _, _, j in ref_jobs] + list(student_jobs.values()))
        files = {}
        for (what, key, _), r in zip(ref_jobs, rendered, strict=False):
            name = "mean" if what == "mean" else json.dumps(list(key))
            files[name] = {"image": str(tmp_path / f"{len(files)}.exr"), "spp": r.spp}
            write_exr(Path(files[name]["image"]), r.image)
            if what == "mean":
                files["variance"] = str(tmp_path / "variance.exr")
                write_exr(Path(files["variance"]), r.variance)
        reference = {"mean": files["mean"]["image"], "variance": files["variance"], "spp": files["mean"]["spp"]}
        for student, r in zip(student_jobs, rendered[len(ref_jobs) :], strict=True):
            files[student] = {"image": str(tmp_path / f"{student}.exr"), "spp": r.spp, "seconds": r.seconds}
            write_exr(Path(files[student]["image"]), r.image)
        for s in subs:
            p = prepared[s.student]
            base = None
            if p["key"]:
                base = pool.submit(tasks.measure_baseline, text, reference, files[json.dumps(p["key"])], p["key"],
                                   p["encoding"]).result()  # fmt: skip
            out = pool.submit(tasks.grade_metrics, text, p, str(tmp_path / "out" / s.student),
                              submission=str(tmp_path / s.student), render=files.get(s.student),
                              reference=reference, baseline=base).result()  # fmt: skip
            expected = mine[s.student].to_json() | {"render_seconds": 0}
            assert out["report"] | {"render_seconds": 0} == json.loads(json.dumps(expected)), s.student
            assert (out["score"], out["max_score"]) == (mine[s.student].score, mine[s.student].max_score)
            from PIL import Image

            for name, pixels in mine[s.student].images.items():
                got = np.asarray(Image.open(tmp_path / "out" / s.student / f"{name}.png"))
                np.testing.assert_array_equal(got, pixels)


# ------------------------------------------------------------------------------------- restarts


def test_grading_run_resumes_after_a_restart_keeping_its_renders(tmp_path):
    """`python -m server` is killed (SIGKILL) with part of a class rendered; started again, it takes the run
    up from its rows: every render job it had queued is found by id, the finished ones are used as they
    are (not queued or rendered again), the others waited for; the grades are those of an uncut run."""
    data = tmp_path / "data"
    server = Server(data, workers=1).start()
    try:
        run = upload(server.client, slow_class())
        caught_mid_run(server.client, run["url"])
        family = children(server.proc.pid)
        assert len(family) >= 2  # its render worker and its grading processes
        server.stop(signal.SIGKILL)
        # the server's processes end with it: the render worker gives its job back, the grading processes stop
        wait_for(lambda: not any(pid_alive(p) for p in family), 60, f"the server's processes {family} to end")
        before = snapshot(data, run["id"])
        first_log = server.log_path
        server = Server(data, workers=1).start()
        state = wait_for(lambda: (s := server.client.get(run["url"]).json())["status"] != "running" and s, 300,
                         "the resumed run", interval=0.2)  # fmt: skip
        assert state["status"] == "done", state
        assert state["resumed"] == 1 and scores(state) == SLOW_GRADES
        after = snapshot(data, run["id"])
        check_resumed(before, after, state)
        # the second server rendered none of the jobs that were done: its workers' log never took them
        log = server.log_path.read_text()
        assert first_log != server.log_path
        assert f"grading run {run['id']}: resumed" in log
        done_before = [j for j, row in before["jobs"].items() if row["status"] == "done"]
        assert not [j for j in done_before if f"job {j}: rendering" in log]
        assert sum(f"job {j}: rendering" in log for j in after["jobs"]) >= 1  # what was left was rendered here
    finally:
        server.stop()


def test_grading_run_survives_a_dead_grading_process(tmp_path, caplog):
    """A grading process killed while it works (here: at once, while it loads): the tasks it had are
    given again (one at a time) and every student gets the grade of an undisturbed run."""
    with api_client(tmp_path / "data", workers=1, grading_processes=1) as client:
        pool = client.app.state.grade_runs.pool
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as z:
            for f in sorted(CLASS.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(CLASS).as_posix())
        run = upload(client, buf.getvalue())
        pid = wait_for(lambda: pool.pids() and pool.pids()[0], 60, "a grading process", interval=0.01)
        os.kill(pid, signal.SIGKILL)
        state = wait_for(lambda: (s := client.get(run["url"]).json())["status"] != "running" and s, 240, "the run")
        assert state["status"] == "done", state
        assert scores(state) == EXAMPLE_GRADES
        assert pool.pids() and pool.pids()[0] != pid  # a new process took over
    assert "a grading process died: starting new ones" in caplog.text


def test_grading_runs_from_before_the_tables_are_imported(tmp_path):
    """A data directory from before the tables: its runs (status.json in their folders) are read into
    them at start-up, so their summaries and reports stay reachable; one that was running is failed."""
    grades = tmp_path / "data" / "grades"
    done, cut = "a" * 32, "b" * 32
    row = {"student": "alice", "kind": "scene", "status": "graded", "score": 13.0, "max_score": 13.0, "percent": 100.0}
    for run_id, status in ((done, "done"), (cut, "running")):
        (grades / run_id / "out" / "alice").mkdir(parents=True)
        (grades / run_id / "assignment.json").write_text(assignment_text())
        summary = {"assignment": "HW 4", "statistics": {"students": 1}, "students": [row]} if status == "done" else None
        (grades / run_id / "status.json").write_text(json.dumps({
            "id": run_id, "status": status, "assignment": "HW 4", "created_at": 1.0, "finished_at": 2.0,
            "error": None, "students": ["alice"], "renders_done": 3, "renders_total": 3, "max_score": 13,
            "summary": summary}))  # fmt: skip
        (grades / run_id / "out" / "alice" / "report.json").write_text(json.dumps({"student": "alice", "score": 13}))
    with api_client(tmp_path / "data", workers=0) as client:
        state = client.get(f"/api/grade/{done}").json()
        assert (state["status"], state["students"], state["summary"]["students"]) == ("done", ["alice"], [row])
        assert state["reports"] == [{"student": "alice", "score": 13}]
        cut_state = client.get(f"/api/grade/{cut}").json()
        assert cut_state["status"] == "failed"
        assert "submit it again" in cut_state["error"]


# ------------------------------------------------------------------------------ the Redis backend


@pytest.fixture(scope="module")
def redis_server(tmp_path_factory):
    from tests.support.queue import RedisServer

    with RedisServer(tmp_path_factory.mktemp("redis") / "redis.log") as r:
        yield r


def test_grading_run_resumes_on_the_redis_backend(redis_server, tmp_path):
    """The same restart with the jobs on a worker host through Redis: the API is killed mid-run while the
    host goes on rendering; started again, the API applies what the host did meanwhile and the run takes
    up its jobs by id, none queued twice, none rendered twice."""
    from tests.support.queue import Api, Process, worker_argv

    url = redis_server.url
    data = tmp_path / "data"
    api = Api(data, url).start()
    host = Process(worker_argv(url, "host-g", threads=2), tmp_path / "host-g.log").start()
    try:
        api.wait_hosts(1)
        run = upload(api.client, slow_class())
        caught_mid_run(api.client, run["url"])
        api.stop(signal.SIGKILL)  # its process group: the API and its grading processes
        before = snapshot(data, run["id"])
        api = Api(data, url, port=api.port).start()  # waits for the dead API's mark in Redis to expire
        state = wait_for(lambda: (s := api.client.get(run["url"]).json())["status"] != "running" and s, 300,
                         "the resumed run", interval=0.2)  # fmt: skip
        assert state["status"] == "done", state
        assert state["resumed"] == 1 and scores(state) == SLOW_GRADES
        after = snapshot(data, run["id"])
        check_resumed(before, after, state)
        rendered = re.findall(r"job (\S+): done", host.log_path.read_text())
        assert sorted(rendered) == sorted(after["jobs"])  # each job rendered once, all of them on the host
    finally:
        host.stop()
        api.stop()
