"""A course assignment on a full disk (issue #39, items 1 and 2), on a small tmpfs the test mounts as the data
directory and fills (tests/server/core/test_disk_full.py's helpers).

- The version's grading run outlives the full disk (met while it grades a submission: the test holds the run's
  thread through a listener while it fills the disk): it waits for space (/api/health says so), its row stays
  `running` with its thread, and once there is space the next submission (or the janitor's round) wakes it and
  the step that failed is done again: the submission it was grading is graded, and so is the new one.
- A 507 keeps nothing: neither the submission's row (no attempt counted) nor its file, here or in the run; and it
  comes as fast as a 202."""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from pathlib import Path

from server.jobs.janitor import Janitor
from tests.support.api import INSTRUCTOR, bearer, course_client, wait_for
from tests.support.assignments import T0, finished, publish, roster, scene_text, submit
from tests.support.disk import filled, is_507, tmpfs


def rows(data: Path, sql: str, *args) -> list[tuple]:
    db = sqlite3.connect(data / "jobs.sqlite3")
    try:
        return db.execute(sql, args).fetchall()
    finally:
        db.close()


def files_of(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


def test_a_grading_run_waits_out_a_full_disk_and_a_507_keeps_nothing(tmp_path):
    # the janitor's rounds are far apart here: what wakes the run is the submission made once there is space
    with tmpfs(tmp_path / "data") as data, course_client(data, T0, janitor_interval=3600) as app:
        a = publish(app, max_submissions=2)
        aid = a["id"]
        tok = {k: v["token"] for k, v in roster(app, aid, [("s1", "Alice", "a@x"), ("s2", "Bob", "b@x")]).items()}

        def reference_done():
            got = app.get(f"/api/assignments/{aid}").json()
            return (got.get("reference_grade") or {}).get("status") not in (None, "queued", "grading") and got

        run_id = wait_for(reference_done, 240, "the reference's grade", interval=0.2)["run_id"]

        # the run's thread is held (by a listener: it tells the course when a student's row moves) right after it
        # kept the first submission's prepared row, while the test fills the disk: its next step meets it
        hold, held = threading.Event(), threading.Event()

        def pause(run: str, student: str) -> None:
            if run == run_id and student != "reference" and not held.is_set():
                held.set()
                hold.wait(120)

        app.app.state.grade_runs.listeners.append(pause)
        started = time.perf_counter()
        carol = submit(app, aid, tok["s1"], {"scene": scene_text("carol")})  # invalid: graded without a render
        accepted = time.perf_counter() - started
        assert held.wait(120), "the run never prepared the submission"
        with filled(data):
            hold.set()
            # the run meets the full disk while it grades alice: it waits, its row running, its thread alive
            health = wait_for(lambda: (h := app.get("/api/health").json())["grading"]["waiting_for_space"] and h,
                              120, "the run to wait for space", interval=0.1)  # fmt: skip
            assert health["grading"]["since"] is not None and health["status"] == "ok", health
            assert rows(data, "SELECT status FROM grading_runs WHERE id = ?", run_id) == [("running",)]
            assert app.app.state.grade_runs.threads[run_id].is_alive()
            before = files_of(data / "course" / aid), files_of(data / "grades" / run_id / "submissions")

            started = time.perf_counter()
            r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": scene_text("bob")},
                         headers=bearer(tok["s2"]))  # fmt: skip
            refused = time.perf_counter() - started
            is_507(r)
            assert refused < max(2.0, 5 * accepted), (refused, accepted)  # no wait: as long as a 202
            # nothing of it: no row (no attempt), no file in the course's folder or the run's
            assert rows(data, "SELECT COUNT(*) FROM course_submissions WHERE student = 's2'") == [(0,)]
            items = rows(data, "SELECT COUNT(*) FROM grading_items WHERE run_id = ?", run_id)
            assert items == [(2,)], items  # the reference and carol
            assert (files_of(data / "course" / aid), files_of(data / "grades" / run_id / "submissions")) == before
            left = app.get(f"/api/assignments/{aid}", headers=bearer(tok["s2"])).json()["submissions_left"]
            assert left == 2
            assert app.get(f"/api/assignments/{aid}/submissions/{carol['id']}").json()["status"] == "grading"

        # space again: the next submission is taken, wakes the run, and both are graded
        bob = submit(app, aid, tok["s2"], {"scene": json.loads(scene_text("alice"))})
        graded = {s: finished(app, aid, sub["id"]) for s, sub in (("carol", carol), ("bob", bob))}
        assert {s: g["status"] for s, g in graded.items()} == {"carol": "invalid", "bob": "graded"}, graded
        assert graded["bob"]["score"] is not None and graded["bob"]["score"] > 0, graded
        assert app.get("/api/health").json()["grading"] == {"waiting_for_space": 0, "since": None}
        assert rows(data, "SELECT status FROM grading_runs WHERE id = ?", run_id) == [("running",)]  # still open
        assert rows(data, "SELECT COUNT(*) FROM course_submissions WHERE handed = 0") == [(0,)]
        assert app.get(f"/api/assignments/{aid}", headers=bearer(INSTRUCTOR)).status_code == 200


def test_the_janitors_round_runs_its_chores(tmp_path):
    """GradeRuns.retry is one of the janitor's chores: a round wakes the runs that wait for space."""
    from server.core.settings import Settings
    from server.jobs.store import JobStore

    called = []
    store = JobStore(tmp_path)
    try:
        janitor = Janitor(Settings(data_dir=tmp_path), store, chores=(lambda: called.append(1), lambda: 1 / 0))
        janitor.clean()
        janitor.clean()
    finally:
        store.close_connections()
    assert called == [1, 1]
