"""The service's grading runs (POST /api/grade, POST /api/grade/upload): started, resumed, read.

A run is rows in SQLite (server/grading/store.py) and files under <data_dir>/grades/<id>/; a thread of the
API process drives it (server/grading/run.py) and a restarted server resumes it from its rows. The grader's
renders are jobs that the render workers take like any other (through the job service), each with the
assignment's time limit, so one slow or broken submission fails alone while the others go on; each
student's other work runs in the grading processes (server/grading/pool.py).

A full disk never ends a run (server/grading/run.py): its thread waits for space (`waiting`, shown by
/api/health) and is woken by `retry`, which the janitor calls each round and a new submission calls too; `retry`
also starts a thread for any run that is `running` without one.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache, partial
from pathlib import Path
from typing import cast

from server.core.files import write_atomic
from server.core.settings import Settings
from server.grading.pool import GradingPool
from server.grading.run import GradingRun
from server.grading.run_base import RunContext
from server.grading.store import GradingStore, ItemWithReport, Stage
from server.jobs.lifecycle import JobStatus
from server.jobs.service import JobService
from tracer.grading import AssignmentError, Grader, load_assignment

log = logging.getLogger(__name__)

STUDENT_FILES = {  # what GET /api/grade/{id}/students/{student}/{file} serves
    "render.png": "image/png", "reference.png": "image/png", "error_map.png": "image/png",
    "rejected.png": "image/png", "results.json": "application/json", "report.json": "application/json",
}  # fmt: skip


@lru_cache(maxsize=64)
def max_scores(text: str, scene_points: float | None) -> dict[str, float | None]:
    """A run's maximum per kind of submission: a scene's (the run's `max_score`) and an image's, the image
    tests' points alone (validity and the requirements are a scene's); the image's None for a spec this version
    no longer reads."""
    try:
        image = load_assignment(text)[0].max_score("image")
    except AssignmentError:
        image = None
    return {"scene": scene_points, "image": image}


@dataclass
class Handed:
    """A submission handed to a new run: its file's bytes (`data`), or a file (`path`, an upload's, on
    the data directory's disk) that the run takes into its folder."""

    student: str
    kind: str  # scene, png or exr
    filename: str  # as submitted
    data: bytes | None = None
    path: Path | None = None


SUFFIX = {"scene": ".json", "png": ".png", "exr": ".exr"}


def _link_or_copy(src: Path, tmp: Path) -> None:
    """`src` at `tmp`: a hard link (no byte written: a submission's file goes into its run on a full disk too),
    or a copy where links are not allowed."""
    try:
        os.link(src, tmp)
    except OSError:
        shutil.copyfile(src, tmp)


class GradeRuns:
    """The service's grading runs: start one, read its state, resume the unfinished ones at start-up.

    A run's status is a job's (server/jobs/lifecycle.py): running, then done or failed. Its record is rows
    in the job store's database (server/grading/store.py); its files are in <data_dir>/grades/<id>/:
    submissions/ (the files handed in), renders/ (the images its render jobs made, linked there as soon
    as each job ends, so the janitor may remove the jobs), out/ (each student's report and pictures,
    the class summary). `resume()` takes up every run a stopped server left running."""

    def __init__(self, settings: Settings, jobs: JobService):
        self.settings, self.jobs, self.store = settings, jobs, jobs.store
        self.root = settings.data_dir / "grades"
        self.root.mkdir(parents=True, exist_ok=True)
        self.uploads = self.root / ".uploads"  # uploads being unpacked (a crash leaves them: removed here)
        shutil.rmtree(self.uploads, ignore_errors=True)
        self.gs = GradingStore(settings.data_dir)
        self.pool = GradingPool(
            settings.grading_processes or os.cpu_count() or 1, settings.worker_nice, settings.preload_mesh_reader
        )
        self.stopping = threading.Event()
        self.threads: dict[str, threading.Thread] = {}
        self._wakes: dict[str, threading.Event] = {}  # an open run's: set when a student is added
        self._wakes_lock = threading.Lock()
        self.waiting: dict[str, tuple[float, str]] = {}  # runs waiting for space on the disk: (since, why)
        self.listeners: list[Callable[[str, str], None]] = []  # told (run, student) when a student's stage moves
        self.context = RunContext(settings, self.gs, jobs, self.pool, self.root, self.stopping, self.wake,
                                  self.item_changed, self._waiting_space)  # fmt: skip
        self._import_legacy()

    # -- starting, resuming, stopping

    def staging(self) -> Path:
        """A fresh folder for an upload's files, on the data directory's disk (a run takes them by renaming)."""
        path = self.uploads / uuid.uuid4().hex
        path.mkdir(parents=True)
        return path

    def start(self, assignment: dict, handed: list[Handed], open_: bool = False) -> dict:
        """Check the assignment (AssignmentError with paths), keep the submissions and the run's rows,
        then grade in a thread; the run's state. An `open_` run takes more submissions as they come (`add`),
        sharing its reference renders with all of them, until it is `close`d (a course's assignment)."""
        text = json.dumps(assignment)
        spec, _ = load_assignment(text)
        Grader(spec, None)  # raises for a reference scene given as a file name, or one that does not validate
        run_id = uuid.uuid4().hex
        folder = self.root / run_id
        try:
            (folder / "submissions").mkdir(parents=True)
            (folder / "assignment.json").write_text(text)
            items = []
            for i, h in enumerate(handed):
                rel = f"submissions/{i:05d}{SUFFIX[h.kind]}"
                if h.path is not None:
                    os.replace(h.path, folder / rel)
                else:
                    (folder / rel).write_bytes(h.data or b"")
                items.append({"student": h.student, "kind": h.kind, "filename": h.filename, "file": rel})
            # one transaction: all rows or none
            self.gs.create_run(run_id, text, spec.name, spec.max_score(), items, open_)
        except BaseException:  # a full disk: no half-written run is left behind
            shutil.rmtree(folder, ignore_errors=True)
            raise
        log.info("grading run %s: %d submission(s) for %s", run_id, len(items), spec.name)
        self._spawn(run_id)
        made = self.state(run_id)
        assert made is not None  # written just above
        return made

    def add(self, run_id: str, h: Handed) -> bool:
        """One more submission for an open run (its file kept in the run's folder, then its row); False if
        the run has that student already: handing the same submission again grades it once."""
        if self.gs.item(run_id, h.student) is not None:
            return False
        item = self.place(run_id, h)
        added = self.gs.add_item(run_id, item)
        self.added(run_id)
        return added

    def place(self, run_id: str, h: Handed) -> dict:
        """A submission's file put into an open run's folder (a hard link to an upload's file where it can be:
        no byte written), before its row: the row's dict for `GradingStore.add_item`. A caller whose row is not
        written takes the file away again (`unplace`)."""
        rel = f"submissions/{h.student}{SUFFIX[h.kind]}"
        path = self.root / run_id / rel
        if h.path is not None:
            write_atomic(path, partial(_link_or_copy, h.path))
        else:
            write_atomic(path, lambda tmp: tmp.write_bytes(h.data or b""))
        return {"student": h.student, "kind": h.kind, "filename": h.filename, "file": rel}

    def unplace(self, run_id: str, item: dict) -> None:
        """`place` undone: the file of a submission whose row was not written."""
        (self.root / run_id / item["file"]).unlink(missing_ok=True)

    def added(self, run_id: str) -> None:
        """A student was added to the open run `run_id`: its thread looks (and a run waiting for space tries
        again: the disk may have room now)."""
        self.wake(run_id).set()
        self.retry()

    def retry(self) -> None:
        """Every run waiting for space tries again now, and a run left `running` without a thread (one that
        stopped on something unforeseen) gets one. The janitor calls it each round."""
        for run_id in list(self.waiting):
            self.wake(run_id).set()
        if self.stopping.is_set():
            return
        for run_id in self.gs.running():
            thread = self.threads.get(run_id)
            if thread is None or not thread.is_alive():
                log.warning("grading run %s: running without a thread; taken up again", run_id)
                self._spawn(run_id)

    def _waiting_space(self, run_id: str, why: str | None) -> None:
        if why is None:
            self.waiting.pop(run_id, None)
        else:
            self.waiting.setdefault(run_id, (time.time(), why))

    def health(self) -> dict:
        """For /api/health: the runs waiting for space on the disk (and since when, Unix time)."""
        waiting = dict(self.waiting)
        return {
            "waiting_for_space": len(waiting),
            "since": min((since for since, _ in waiting.values()), default=None),
        }

    def close(self, run_id: str) -> None:
        """An open run takes no more submissions: it ends once those it has are graded."""
        self.gs.close(run_id)
        self.wake(run_id).set()

    def item_changed(self, run_id: str, student: str) -> None:
        """From a run's thread: a student's row moved (prepared, rendered, graded); the listeners are told."""
        for listener in self.listeners:
            try:
                listener(run_id, student)
            except Exception:  # a listener's bug never stops a run
                log.exception("grading run %s: a listener failed", run_id)

    def wake(self, run_id: str) -> threading.Event:
        """The event that wakes an open run's thread (set: look for new students)."""
        with self._wakes_lock:
            return self._wakes.setdefault(run_id, threading.Event())

    def item(self, run_id: str, student: str) -> ItemWithReport | None:
        """One student's row (stage, status, exact score) and their report.json once graded."""
        it = cast("ItemWithReport | None", self.gs.item(run_id, student))
        if it is not None and it["stage"] == Stage.graded:
            path = self.root / run_id / "out" / student / "report.json"
            it["report"] = json.loads(path.read_text()) if path.is_file() else None
        return it

    def resume(self) -> list[str]:
        """Take up the runs a stopped server left running (call it once the job queue has started: their
        render jobs are back in the queue by then)."""
        ids = self.gs.running()
        for run_id in ids:
            self.gs.resumed(run_id)
            log.info("grading run %s: resumed", run_id)
            self._spawn(run_id)
        return ids

    def _spawn(self, run_id: str) -> None:
        with self._wakes_lock:  # one thread per run (start and retry may both come)
            old = self.threads.get(run_id)
            if old is not None and old.is_alive():
                return
            run = GradingRun(self.context, run_id)
            thread = threading.Thread(target=self._drive, args=(run,), name=f"grading-{run_id[:8]}", daemon=True)
            self.threads = {k: t for k, t in self.threads.items() if t.is_alive()}  # the runs still going
            self.threads[run_id] = thread
            thread.start()

    def _drive(self, run: GradingRun) -> None:
        try:
            run.run()
        finally:
            self.waiting.pop(run.id, None)

    def shutdown(self) -> None:
        """At the server's shutdown: the runs stop where they are (their rows say where) and the grading
        processes end; the next server resumes the runs."""
        self.stopping.set()
        with self._wakes_lock:
            for event in self._wakes.values():  # a run waiting for space stops waiting
                event.set()
        deadline = time.monotonic() + 10  # for all of them together: a stopping server exits in seconds
        for thread in self.threads.values():
            thread.join(timeout=max(0.0, deadline - time.monotonic()))
        self.pool.shutdown()

    # -- reading

    def folder(self, run_id: str) -> Path | None:
        if len(run_id) != 32 or not all(c in "0123456789abcdef" for c in run_id):
            return None
        return self.root / run_id if self.gs.run(run_id) is not None else None

    def state(self, run_id: str) -> dict | None:
        row = self.gs.run(run_id) if self.folder(run_id) else None
        if row is None:
            return None
        progress = self.gs.progress(run_id)
        return {
            "id": run_id, "status": row["status"], "assignment": row["name"], "created_at": row["created_at"],
            "finished_at": row["finished_at"], "error": row["error"], "students": self.gs.students(run_id),
            "renders_done": progress["renders_done"], "renders_total": row["renders_total"],
            "graded": progress["stages"]["graded"], "max_score": row["max_score"],
            "max_scores": max_scores(row["assignment"], row["max_score"]),
            "summary": json.loads(row["summary"]) if row["summary"] else None, "resumed": row["starts"] - 1,
            "open": self.gs.is_open(run_id),
        }  # fmt: skip

    def reports(self, run_id: str) -> list[dict]:
        """Each graded student's report.json, in the class's order."""
        folder = self.folder(run_id)
        out: list[dict] = []
        if folder is None:
            return out
        for it in self.gs.items(run_id):
            path = folder / "out" / it["student"] / "report.json"
            if it["stage"] == Stage.graded and path.is_file():
                out.append(json.loads(path.read_text()))
        return out

    # -- runs of a server from before the database kept them (a status.json in their folder)

    def _import_legacy(self) -> None:
        for status in sorted(self.root.glob("*/status.json")):
            run_id = status.parent.name
            if self.folder(run_id) is not None or len(run_id) != 32:
                continue
            try:
                state = json.loads(status.read_text())
                text = (status.parent / "assignment.json").read_text()
            except (OSError, ValueError):
                continue
            if state.get("status") == JobStatus.running:
                state.update(status=JobStatus.failed, error="the server stopped while grading; submit it again")
            rows = {r["student"]: r for r in (state.get("summary") or {}).get("students", [])}
            items = [{"student": s, "kind": (rows.get(s) or {}).get("kind", "scene"), "filename": "", "file": ""}
                     for s in state.get("students", [])]  # fmt: skip
            self.gs.create_run(run_id, text, state.get("assignment") or "", state.get("max_score") or 0, items)
            for s in state.get("students", []):
                if s in rows:
                    row = rows[s]
                    self.gs.update_item(run_id, s, stage=Stage.graded, status=row["status"], score=row["score"],
                                        max_score=row["max_score"], row=row)  # fmt: skip
            self.gs.update_run(run_id, status=state["status"], error=state.get("error"),
                               created_at=state.get("created_at") or 0, finished_at=state.get("finished_at"),
                               renders_total=state.get("renders_total"),
                               summary=json.dumps(state["summary"]) if state.get("summary") else None)  # fmt: skip
            log.info("grading run %s: imported from its status.json", run_id)
