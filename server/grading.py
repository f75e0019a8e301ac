"""Grading through the job queue: the grader's renders become jobs that the render workers take like
any other, each with the assignment's time limit, so one slow or broken submission fails alone
(its worker is stopped at the limit, or dies and is replaced) while the others go on.

- `GradeRuns`: the service's grading runs (POST /api/grade, POST /api/grade/upload). A run is rows in
  SQLite (server/grading_store.py) and files under <data_dir>/grades/<id>/; a thread of the API
  process drives it (server/grading_run.py) and a restarted server resumes it from its rows.
- `GradingPool`: the worker processes where each student's work is done (tracer/grading/tasks.py:
  reading and checking a submission, the image tests): never in the API process.
- `QueueRenderer`: a tracer.grading renderer that submits jobs to the service's queue and waits for
  them (the CLI renders without the service: tracer/grading/local.py).
"""

from __future__ import annotations

import json
import logging
import multiprocessing as mp
import os
import shutil
import signal
import threading
import time
import uuid
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path

from server.grading_store import GradingStore, Stage
from server.lifecycle import JobStatus, Lane
from server.settings import Settings
from server.store import JobFile, JobStore
from tracer.grading import Grader, Rendered, RenderJob, load_assignment
from tracer.grading.grade import over_time
from tracer.scene import Limits, SceneError, load_scene

log = logging.getLogger("server.grading")

POLL = 0.1  # seconds between two looks at the grading jobs' rows
STUDENT_FILES = {  # what GET /api/grade/{id}/students/{student}/{file} serves
    "render.png": "image/png", "reference.png": "image/png", "error_map.png": "image/png",
    "rejected.png": "image/png", "results.json": "application/json", "report.json": "application/json",
}  # fmt: skip


class QueueRenderer:
    """Renders a grader's jobs as queued render jobs, and waits for all of them.

    `queued(row)` hands each job the store has queued to the job queue (wakes an idle worker, or puts
    it in Redis); `on_progress(done, total)` follows the renders; `max_queued` is passed to the store
    (grading may queue a whole class at once)."""

    def __init__(
        self,
        store: JobStore,
        queued: Callable[[dict], None] | None = None,
        on_progress: Callable[[int, int], None] | None = None,
        max_queued: int = 1_000_000,
        settings: Settings | None = None,
        log_path: Path | None = None,
    ):
        self.store, self.queued, self.on_progress, self.max_queued = store, queued, on_progress, max_queued
        self.settings = settings  # the service's own limits also apply (the smaller of the two)
        self.log_path = log_path  # where the workers log, when they have a file of their own (the CLI's)

    def _capped(self, job: RenderJob) -> tuple[Limits, float, str]:
        return capped(job, self.settings)

    def __call__(self, jobs: list[RenderJob]) -> list[Rendered]:
        out: list[Rendered | None] = [None] * len(jobs)
        ids: dict[int, str] = {}
        limit: dict[int, tuple[float, str]] = {}  # seconds and what set them
        for i, job in enumerate(jobs):
            limits, seconds, source = self._capped(job)
            limit[i] = (seconds, source)
            try:
                scene, warnings = load_scene(job.scene, limits)
            except SceneError as e:
                out[i] = Rendered(error="invalid scene: " + "; ".join(f"{x['path']}: {x['message']}" for x in e.errors))
                continue
            row = self.store.create(
                json.dumps(job.scene), name=f"grading: {job.name}"[:200], width=scene.film.width,
                height=scene.film.height, spp=scene.sampler.spp, priority=job.priority, warnings=warnings,
                max_seconds=seconds, max_queued=self.max_queued, lane=Lane.batch,
            )  # fmt: skip
            ids[i] = row["id"]
            if self.queued:
                self.queued(row)
        pending = dict(ids)
        total = len(jobs)
        while pending:
            for i, job_id in list(pending.items()):
                row = self.store.get(job_id)
                if row is not None and JobStatus(row["status"]).finished:
                    out[i] = self._result(row, *limit[i])
                    del pending[i]
            if self.on_progress:
                self.on_progress(total - len(pending), total)
            if pending:
                time.sleep(POLL)
        return out  # type: ignore[return-value]

    def _result(self, row: dict, seconds: float, source: str) -> Rendered:
        """A finished job's image and variance, or why there is none."""
        from tracer.film import read_exr

        error, spp, took = job_outcome(row, seconds, source)
        if error is not None:
            return Rendered(error=error)
        try:
            image = read_exr(self.store.job_file(row["id"], JobFile.image_exr))
            variance = read_exr(self.store.job_file(row["id"], JobFile.aov_floats))
        except Exception as e:  # a file missing or broken: that job's result is an error, not the run's
            return Rendered(error=f"the render job {row['id']} left no readable image: {e}")
        return Rendered(image, variance, spp, took)


def capped(job: RenderJob, settings: Settings | None) -> tuple[Limits, float, str]:
    """The job's limits and seconds, each the smaller of the assignment's and the service's, and what
    set the seconds (for the message of a render stopped at its limit)."""
    if settings is None:
        return job.limits, job.max_seconds, job.limit_source
    limits = job.limits.tighter(settings.limits)
    if settings.max_job_seconds < job.max_seconds:
        return limits, settings.max_job_seconds, "the server's max_job_seconds, TRACER_MAX_JOB_SECONDS"
    return limits, job.max_seconds, job.limit_source


def job_outcome(row: dict, seconds: float, source: str) -> tuple[str | None, int, float]:
    """A finished job's row -> (why it has no image, or None; its spp; its render seconds). A job
    stopped at its time limit says what set the limit (`source`): the worker knows its row's seconds,
    not where they came from, so its message is replaced."""
    if row["status"] != JobStatus.done:
        error = row["error"] or f"the render job {row['id']} was {row['status']}"
        if row["status"] == JobStatus.failed and "over the time limit" in error:
            killed = "; its worker was killed" if "killed" in error else ""
            error = over_time(seconds, source) + killed
        return error, 0, 0.0
    took = (row["finished_at"] or 0) - (row["started_at"] or 0)
    return None, int(row["spp_done"]), max(0.0, took)


# ----------------------------------------------------------------------------------- the processes


PARENT_CHECK = 1.0  # seconds between a grading process's looks at whether the server is still there


def _pool_process(nice: int) -> None:
    """A grading process starts: below the API (like the render workers), deaf to the terminal's Ctrl-C and
    the group's SIGTERM (the server stops the pool), watching that the server lives, the grading modules
    loaded before the first task."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the group's stop signal too: the server ends the pool
    if nice:
        os.nice(nice)
    # one thread per process, before FLIP loads its OpenMP runtime: the pool is the parallelism, and OpenMP's
    # threads spinning on cores the renders use made a 96x72 FLIP take 100 ms instead of 7 (bench/grading.py)
    os.environ["OMP_NUM_THREADS"] = "1"
    threading.Thread(target=_watch_parent, args=(os.getppid(),), name="parent-watch", daemon=True).start()
    import tracer.grading.tasks  # noqa: F401  (numpy, FLIP, scikit-image: once per process)


def _watch_parent(parent: int) -> None:
    """End this process once its server is gone (killed without a word: SIGKILL, out of memory). Python's
    pool cannot tell: each process holds both ends of the pipe it waits on, so it would wait forever."""
    while True:
        time.sleep(PARENT_CHECK)
        if os.getppid() != parent:
            os._exit(0)


class GradingPool:
    """Worker processes for the runs' per-student work (tracer/grading/tasks.py): `processes` of them,
    spawned (nothing of the API's state crosses: tasks are plain data), niced like the render workers,
    started at the first task and kept. A process that dies breaks Python's pool: the next `submit`
    starts a new one, and each run submits again what it had lost (server/grading_run.py)."""

    def __init__(self, processes: int, nice: int = 0):
        self.processes, self.nice = max(1, processes), nice
        self._executor: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()
        self.closed = False

    def _new(self) -> ProcessPoolExecutor:
        ctx = mp.get_context("spawn")
        return ProcessPoolExecutor(self.processes, mp_context=ctx, initializer=_pool_process, initargs=(self.nice,))

    def submit(self, fn, /, *args, **kwargs) -> Future:
        with self._lock:
            if self.closed:
                raise RuntimeError("the grading pool is shut down")
            if self._executor is None:
                self._executor = self._new()
            try:
                return self._executor.submit(fn, *args, **kwargs)
            except BrokenProcessPool:
                log.warning("a grading process died: starting new ones")
                self._executor.shutdown(wait=False, cancel_futures=True)
                self._executor = self._new()
                return self._executor.submit(fn, *args, **kwargs)

    def pids(self) -> list[int]:
        executor = self._executor
        return sorted((getattr(executor, "_processes", None) or {}).keys()) if executor else []

    def shutdown(self) -> None:
        with self._lock:
            self.closed = True
            if self._executor is not None:
                self._executor.shutdown(wait=False, cancel_futures=True)
                self._executor = None


# ---------------------------------------------------------------------------------------- the runs


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


class GradeRuns:
    """The service's grading runs: start one, read its state, resume the unfinished ones at start-up.

    A run's status is a job's (server/lifecycle.py): running, then done or failed. Its record is rows
    in the job store's database (server/grading_store.py); its files are in <data_dir>/grades/<id>/:
    submissions/ (the files handed in), renders/ (the images its render jobs made, linked there as soon
    as each job ends, so the janitor may remove the jobs), out/ (each student's report and pictures,
    the class summary). `resume()` takes up every run a stopped server left running."""

    def __init__(self, settings: Settings, store: JobStore, queued: Callable[[dict], None] | None):
        self.settings, self.store, self.queued = settings, store, queued
        self.root = settings.data_dir / "grades"
        self.root.mkdir(parents=True, exist_ok=True)
        self.uploads = self.root / ".uploads"  # uploads being unpacked (a crash leaves them: removed here)
        shutil.rmtree(self.uploads, ignore_errors=True)
        self.gs = GradingStore(settings.data_dir)
        self.pool = GradingPool(settings.grading_processes or os.cpu_count() or 1, settings.worker_nice)
        self.stopping = threading.Event()
        self.threads: dict[str, threading.Thread] = {}
        self._import_legacy()

    # -- starting, resuming, stopping

    def staging(self) -> Path:
        """A fresh folder for an upload's files, on the data directory's disk (a run takes them by renaming)."""
        path = self.uploads / uuid.uuid4().hex
        path.mkdir(parents=True)
        return path

    def start(self, assignment: dict, handed: list[Handed]) -> dict:
        """Check the assignment (AssignmentError with paths), keep the submissions and the run's rows,
        then grade in a thread; the run's state."""
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
            self.gs.create_run(run_id, text, spec.name, spec.max_score(), items)  # one transaction: all rows or none
        except BaseException:  # a full disk: no half-written run is left behind
            shutil.rmtree(folder, ignore_errors=True)
            raise
        log.info("grading run %s: %d submission(s) for %s", run_id, len(items), spec.name)
        self._spawn(run_id)
        return self.state(run_id)

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
        from server.grading_run import GradingRun

        run = GradingRun(self, run_id)
        thread = threading.Thread(target=run.run, name=f"grading-{run_id[:8]}", daemon=True)
        self.threads = {k: t for k, t in self.threads.items() if t.is_alive()}  # the runs still going
        self.threads[run_id] = thread
        thread.start()

    def shutdown(self) -> None:
        """At the server's shutdown: the runs stop where they are (their rows say where) and the grading
        processes end; the next server resumes the runs."""
        self.stopping.set()
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
            "summary": json.loads(row["summary"]) if row["summary"] else None, "resumed": row["starts"] - 1,
        }  # fmt: skip

    def reports(self, run_id: str) -> list[dict]:
        """Each graded student's report.json, in the class's order."""
        folder = self.folder(run_id)
        out = []
        for it in self.gs.items(run_id) if folder else ():
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
