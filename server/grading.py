"""Grading through the job queue: the grader's renders become jobs that the render workers take like
any other, each with the assignment's time limit, so one slow or broken submission fails alone
(its worker is stopped at the limit, or dies and is replaced) while the others go on.

- `QueueRenderer`: a tracer.grading renderer that submits jobs to the service's queue and waits for them
  (the CLI renders without the service: tracer/grading/local.py).
- `GradeRuns`: grading runs of the service (POST /api/grade): each runs in a thread of the API
  process, keeps its files under <data_dir>/grades/<id>/ and its state in status.json.
"""

from __future__ import annotations

import json
import logging
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path

from server.lifecycle import JobStatus
from server.settings import Settings
from server.store import JobFile, JobStore, write_atomic
from tracer.grading import Grader, Rendered, RenderJob, Submission, load_assignment, write_all
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
        """The job's limits and seconds, each the smaller of the assignment's and the service's, and
        what set the seconds (for the message of a render stopped at its limit)."""
        if self.settings is None:
            return job.limits, job.max_seconds, job.limit_source
        mine = self.settings.limits
        limits = Limits(**{f.name: min(getattr(job.limits, f.name), getattr(mine, f.name)) for f in fields(Limits)})
        if self.settings.max_job_seconds < job.max_seconds:
            return limits, self.settings.max_job_seconds, "the server's max_job_seconds, TRACER_MAX_JOB_SECONDS"
        return limits, job.max_seconds, job.limit_source

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
                max_seconds=seconds, max_queued=self.max_queued,
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
        """A finished job's image and variance, or why there is none. A job stopped at its time limit
        says what set the limit (`source`): the worker knows its row's seconds, not where they came
        from, so its message is replaced."""
        from tracer.film import read_exr

        if row["status"] != JobStatus.done:
            error = row["error"] or f"the render job {row['id']} was {row['status']}"
            if row["status"] == JobStatus.failed and "over the time limit" in error:
                killed = "; its worker was killed" if "killed" in error else ""
                error = over_time(seconds, source) + killed
            return Rendered(error=error)
        try:
            image = read_exr(self.store.job_file(row["id"], JobFile.image_exr))
            variance = read_exr(self.store.job_file(row["id"], JobFile.aov_floats))
        except Exception as e:  # a file missing or broken: that job's result is an error, not the run's
            return Rendered(error=f"the render job {row['id']} left no readable image: {e}")
        seconds = (row["finished_at"] or 0) - (row["started_at"] or 0)
        return Rendered(image, variance, int(row["spp_done"]), max(0.0, seconds))


class GradeRuns:
    """The service's grading runs: start one, read its state; runs left unfinished by a stopped
    server are marked failed at start-up (their render jobs, if queued, still run). A run's status
    is a job's (server/lifecycle.py): running, then done or failed."""

    def __init__(self, settings: Settings, store: JobStore, queued: Callable[[dict], None] | None):
        self.settings = settings
        self.root = settings.data_dir / "grades"
        self.root.mkdir(parents=True, exist_ok=True)
        self.store, self.queued = store, queued
        self._lock = threading.Lock()
        for status in self.root.glob("*/status.json"):
            try:
                state = json.loads(status.read_text())
            except (OSError, ValueError):
                continue
            if state.get("status") == JobStatus.running:
                state.update(status=JobStatus.failed, error="the server stopped while grading; submit it again")
                self._write(status.parent, state)

    def folder(self, run_id: str) -> Path | None:
        if len(run_id) != 32 or not all(c in "0123456789abcdef" for c in run_id):
            return None
        path = self.root / run_id
        return path if (path / "status.json").is_file() else None

    def state(self, run_id: str) -> dict | None:
        folder = self.folder(run_id)
        if folder is None:
            return None
        return json.loads((folder / "status.json").read_text())

    def _write(self, folder: Path, state: dict) -> None:
        text = json.dumps(state)
        write_atomic(folder / "status.json", lambda tmp: tmp.write_text(text))

    def start(self, assignment: dict, submissions: list[Submission]) -> dict:
        """Check the assignment (AssignmentError with paths), then grade in a thread; the run's state."""
        spec, _ = load_assignment(assignment)
        grader = Grader(spec, None)  # raises for a reference scene given as a file name
        run_id = uuid.uuid4().hex
        folder = self.root / run_id
        folder.mkdir(parents=True)
        (folder / "assignment.json").write_text(json.dumps(assignment))
        state = {
            "id": run_id, "status": JobStatus.running, "assignment": spec.name, "created_at": time.time(),
            "finished_at": None, "error": None, "students": [s.student for s in submissions],
            "renders_done": 0, "renders_total": None, "max_score": spec.max_score(), "summary": None,
        }  # fmt: skip
        self._write(folder, state)
        thread = threading.Thread(target=self._run, args=(grader, submissions, folder, state), daemon=True)
        thread.start()
        return state

    def _run(self, grader: Grader, submissions: list[Submission], folder: Path, state: dict) -> None:
        def progress(done: int, total: int) -> None:
            if (done, total) != (state["renders_done"], state["renders_total"]):
                state.update(renders_done=done, renders_total=total)
                with self._lock:
                    self._write(folder, state)

        grader.renderer = QueueRenderer(self.store, self.queued, progress, settings=self.settings)
        try:
            reports = grader.grade(submissions)
            state["summary"] = write_all(folder / "out", reports)
            state["status"] = JobStatus.done
        except Exception as e:  # a bug must end the run with a reason, never leave it "running"
            log.exception("grading run %s failed", folder.name)
            state.update(status=JobStatus.failed, error=f"{type(e).__name__}: {e}")
        state["finished_at"] = time.time()
        with self._lock:
            self._write(folder, state)

    def reports(self, run_id: str) -> list[dict]:
        folder = self.folder(run_id)
        out = []
        for path in sorted((folder / "out").glob("*/report.json")) if folder else ():
            out.append(json.loads(path.read_text()))
        return out
