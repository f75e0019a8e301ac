"""One grading run, driven from its rows by a thread of the API process (server/grading/runs.py starts it,
for a new run and for one a restarted server resumes: the same code, which reads where the run is).

A student's grade goes through `Stage`s, each kept in their row before the next begins:
  submitted -> prepared: in a grading process (tracer.grading.tasks.prepare_submission): validity,
               requirements, and the render the image tests need, which is then queued as a job;
  prepared -> rendered: that job ended; its image is linked into the run's folder (renders/<job>.exr),
               so the janitor may remove the job from then on;
  rendered -> graded: in a grading process (tracer.grading.tasks.grade_metrics): FLIP, SSIM, PSNR and
               the z test against the reference and the noise baseline; report.json and the pictures.
The class's renders (the reference mean; one noise baseline per sampler, spp and light samples) are
rows too, queued first (by priority); each baseline is measured once per way of storing images.

So a resumed run prepares, queues, measures and grades only what its rows say is not done: a render
job it had queued is found by its id (still queued or running: waited for; finished: its image taken,
never rendered again), and only a job that is gone (the janitor removed it before the run took its
image) is queued again.

**A full disk** never ends a run: the step that met it (a row, a report, a render's image) is done again once
there is space. The run's thread waits (`waiting_space`: /api/health says so) until the janitor's next round, a
new submission or SPACE_RETRY seconds wake it, then takes the run up from its rows as a restarted server would.
A render job that failed because the disk was full is queued again; a task that met it in a grading process is
done again, never a student's failure.

Each task goes to the grading processes with at most FLIGHT_PER_PROCESS per process in flight. A
process that dies breaks the pool: the tasks that were in flight become suspects and run again one at
a time, so the one that kills its process is found and fails alone (twice alone: failed).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from server.core.files import is_disk_full
from server.core.settings import Settings
from server.grading.pool import GradingPool
from server.grading.renders import capped, job_outcome
from server.grading.store import GradingStore, RenderStatus, Stage
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, Lane
from server.jobs.service import JobService
from tracer.grading import Grader, Prepared, RenderJob, Report, Submission, load_assignment, tasks
from tracer.grading.batch import class_summary, summary_row, write_report, write_summary
from tracer.grading.imagetests import finish_report
from tracer.scene import Limits, SceneError, load_scene

log = logging.getLogger(__name__)

POLL = 0.2  # seconds between two looks at the run's render jobs
IDLE = 1.0  # seconds between two looks whether the server stops, for an open run with nothing to do
FLIGHT_PER_PROCESS = 2  # tasks of one run in the grading pool at once, per process
MAX_QUEUED = 1_000_000  # a class is queued whole: the queue's limit (TRACER_MAX_QUEUED_JOBS) is for students
SPACE_RETRY = 30.0  # seconds a run that met a full disk waits before it tries again (the janitor wakes it sooner)
JOB_DISK_FULL = "the disk is full"  # in the error of a render job that failed for it (server/queue/render_try.py)
MEAN = "mean"  # the key of the reference mean's row (a baseline's is its [sampler, spp, light_samples])


def _key(it: dict) -> str | None:
    """A prepared student's baseline: its row's key ([sampler, spp, light_samples] as JSON), kept in the item."""
    if "_key" not in it:
        p = it["prepared"]
        it["_key"] = json.dumps(list(p["key"])) if p is not None and p["key"] is not None else None
        it["_enc"] = f"{p['encoding'][0]}/{p['encoding'][1]}" if p is not None else None
    return it["_key"]


def _encoding(it: dict) -> str:
    """How a prepared student's image is stored ("png/8", "render/32"): a baseline is measured once per one."""
    _key(it)
    return it["_enc"]


@dataclass(frozen=True)
class RunContext:
    """What a run needs of the service around it, handed in by GradeRuns (server/grading/runs.py), which this
    module never imports: the runs start their runs, a run only reports back through these."""

    settings: Settings
    gs: GradingStore  # the runs' rows
    jobs: JobService  # the render jobs (and their store's files)
    pool: GradingPool  # the grading processes
    root: Path  # <data_dir>/grades: a run's folder is root/<id>
    stopping: threading.Event  # set when the server stops: the run stops where it is (its rows say where)
    wake: Callable[[str], threading.Event]  # an open run's event, set when a student is added (GradeRuns.add)
    item_changed: Callable[[str, str], None]  # (run, student): a student's row moved; the listeners are told
    waiting_space: Callable[[str, str | None], None]  # (run, why): it waits for space on the disk; None: no more


class GradingRun:
    def __init__(self, context: RunContext, run_id: str):
        self.context, self.id = context, run_id
        self.gs, self.service, self.settings, self.pool = context.gs, context.jobs, context.settings, context.pool
        self.store = context.jobs.store  # the render jobs' files
        self.folder = context.root / run_id
        self.flight: dict[Future, tuple[tuple, bool]] = {}  # future -> (task, submitted alone)
        self.suspects: set[tuple] = set()  # tasks in flight when the pool broke
        self.breaks: dict[tuple, int] = {}  # times a task broke the pool while it ran alone
        self.render_jobs: dict[str, RenderJob] = {}  # the class's render jobs, by key
        self.waited = False  # it met a full disk, and has not gone through a round of its loop since

    def run(self) -> None:
        """The run to its end, or until the server stops. A full disk is waited out (the module's docstring); a
        bug ends the run with a reason, never leaves it "running" (that row too waits for space if it must)."""
        error = None
        while not self.context.stopping.is_set():
            try:
                if error is not None:
                    self.gs.end_run(self.id, JobStatus.failed, error)
                    return
                self._fresh()
                self._load()
                if self._loop():
                    self._finish()
                return
            except Exception as e:
                if is_disk_full(e):
                    self._wait_for_space(e)
                    continue
                if error is not None:  # the failure could not be written: a restarted server takes the run up
                    log.exception("grading run %s: its failure could not be recorded", self.id)
                    return
                log.exception("grading run %s failed", self.id)
                error = f"{type(e).__name__}: {e}"

    def _wait_for_space(self, exc: Exception) -> None:
        """The disk is full: wait until something may have freed space (the janitor's round, a new submission,
        SPACE_RETRY seconds, the server stopping), then the run is taken up again from its rows."""
        log.warning("grading run %s: the disk is full (%s); it waits for space, and goes on from where its rows "
                    "say once there is some", self.id, exc)  # fmt: skip
        self.context.waiting_space(self.id, f"{exc}")  # (since the first time: kept until a round goes through)
        self.waited = True
        woken = self.context.wake(self.id)
        woken.wait(SPACE_RETRY)
        woken.clear()

    def _fresh(self) -> None:
        """Nothing in flight (a run taken up again after a full disk: the tasks it had in flight are done again;
        what they write is the same)."""
        self.flight, self.suspects, self.breaks = {}, set(), {}

    def _load(self) -> None:
        row = self.gs.run(self.id)
        assert row is not None  # the run's own row, written before its thread starts
        self.text = row["assignment"]
        spec, _ = load_assignment(self.text)
        self.grader = Grader(spec, None)
        self.tests = spec.image_tests()
        self.items = {it["student"]: it for it in self.gs.items(self.id)}
        self.renders = {r["key"]: r for r in self.gs.renders(self.id)}
        self.renders_total = row["renders_total"]
        self.open = self.gs.is_open(self.id)

    def _loop(self) -> bool:
        """Until every student is graded (True), or the server stops (False: the rows say where it was). An
        open run (an assignment's version) waits for more students while it is open: `GradeRuns.add` wakes it."""
        if self.grader.reference is not None:
            self._queue_render(MEAN)
        stopping, woken = self.context.stopping, self.context.wake(self.id)
        while not stopping.is_set():
            if woken.is_set():
                woken.clear()
                self._newcomers()
            self._poll_jobs()
            self._schedule()
            if self.waited:  # a round went through: no longer waiting for space
                self.waited = False
                self.context.waiting_space(self.id, None)
            if not self.flight and all(it["stage"] == Stage.graded for it in self.items.values()):
                if not self.open:
                    return True
                woken.wait(IDLE)  # idle until a submission comes (or the server stops)
            elif self.flight:
                done, _ = wait(list(self.flight), timeout=POLL, return_when=FIRST_COMPLETED)
                for future in done:
                    self._collect(future)
            else:
                stopping.wait(POLL)
        return False

    def _newcomers(self) -> None:
        """An open run's students added since it last looked (and whether it is still open)."""
        self.open = self.gs.is_open(self.id)
        last = max((it["position"] for it in self.items.values()), default=-1)
        new = self.gs.items(self.id, after=last)
        if new:
            self.items.update({it["student"]: it for it in new})
            self.renders_total = None  # counted again once they are prepared

    def _finish(self) -> None:
        items = sorted(self.items.values(), key=lambda it: it["position"])
        rows = [it["row"] for it in items]
        table = class_summary(self.grader.assignment.name if rows else None, rows,
                              [(it["score"], it["max_score"]) for it in items])  # fmt: skip
        (self.folder / "out").mkdir(parents=True, exist_ok=True)
        write_summary(self.folder / "out", table)
        self.gs.end_run(self.id, JobStatus.done, summary=table)
        log.info("grading run %s: done, %d students", self.id, len(rows))

    # -- render jobs ----------------------------------------------------------------------------

    def _create(self, job: RenderJob, size: tuple, warnings: list, seconds: float) -> str:
        """Queue a render job (like any other: the queue's backend gets it rendered); its id."""
        width, height, spp = size
        # grading is batch work (the page's renders and ray trees go first), and it reads only the floats
        row = self.service.submit(
            json.dumps(job.scene), name=f"grading: {job.name}"[:200], width=width, height=height, spp=spp,
            priority=job.priority, warnings=warnings, max_seconds=seconds, max_queued=MAX_QUEUED, lane=Lane.batch,
            params={"outputs": "floats"},
        )  # fmt: skip
        return row["id"]

    def _reference_job(self, key: str) -> RenderJob:
        if key not in self.render_jobs:
            wanted = None if key == MEAN else tuple(json.loads(key))
            for what, k, job in self.grader.reference_jobs(set() if wanted is None else {wanted}):
                if (what == "mean") == (wanted is None) and k == wanted:
                    self.render_jobs[key] = job
        return self.render_jobs[key]

    def _queue_render(self, key: str) -> None:
        """The class's render `key` queued once (MEAN, or a baseline's key)."""
        r = self.renders.get(key)
        if r is not None and (r["job_id"] or r["status"] != RenderStatus.waiting):
            return
        if r is None:
            self.gs.add_render(self.id, key)
            r = self.renders[key] = {"key": key, "job_id": None, "status": RenderStatus.waiting, "spp": None,
                                     "seconds": None, "error": None, "measured": {}}  # fmt: skip
        job = self._reference_job(key)
        limits, seconds, _ = capped(job, self.settings)
        try:
            scene, warnings = load_scene(job.scene, limits)
        except SceneError as e:
            error = "invalid scene: " + "; ".join(f"{x['path']}: {x['message']}" for x in e.errors)
            r.update(status=RenderStatus.failed, error=error)
            self.gs.update_render(self.id, key, status=r["status"], error=error)
            return
        size = (scene.film.width, scene.film.height, scene.sampler.spp)
        r["job_id"] = self._create(job, size, warnings, seconds)
        self.gs.update_render(self.id, key, job_id=r["job_id"])

    def _queue_item(self, it: dict) -> None:
        """A student's render queued, once."""
        p = it["prepared"]
        job = _render_job(p["job"])
        _, seconds, _ = capped(job, self.settings)
        it["job_id"] = self._create(job, tuple(p["size"]), p["render_warnings"], seconds)
        self.gs.update_item(self.id, it["student"], job_id=it["job_id"])

    def _poll_jobs(self) -> None:
        """The render jobs this run waits for, in one query: each one that ended is taken in."""
        waiting: dict[str, tuple[str, str]] = {}
        for key, r in self.renders.items():
            if r["status"] == RenderStatus.waiting and r["job_id"]:
                waiting[r["job_id"]] = ("render", key)
        for student, it in self.items.items():
            if it["stage"] == Stage.prepared and it["job_id"]:
                waiting[it["job_id"]] = ("item", student)
        if not waiting:
            return
        states = self.service.states(waiting)
        for job_id, (what, name) in waiting.items():
            row = states.get(job_id)
            if row is not None and not JobStatus(row["status"]).finished:
                continue
            gone = row is None  # removed before we took its image
            if gone or (row["status"] == JobStatus.failed and JOB_DISK_FULL in (row.get("error") or "")):
                why = "is gone" if gone else "met a full disk"
                log.warning("grading run %s: render job %s %s; queued again", self.id, job_id, why)
                if what == "render":
                    self.renders[name]["job_id"] = None
                    self._queue_render(name)
                else:
                    self._queue_item(self.items[name])
                continue
            job = self._reference_job(name) if what == "render" else _render_job(self.items[name]["prepared"]["job"])
            _, seconds, source = capped(job, self.settings)
            error, spp, took = job_outcome(row, seconds, source)
            if error is None:
                try:
                    self._take(job_id, variance=what == "render" and name == MEAN)
                except OSError as e:
                    if is_disk_full(e):
                        raise
                    error = f"the render job {job_id} left no readable image: {e}"
            if what == "render":
                status = RenderStatus.failed if error else RenderStatus.done
                self.renders[name].update(status=status, spp=spp, seconds=took, error=error)
                self.gs.update_render(self.id, name, status=status, spp=spp, seconds=took, error=error)
            else:
                render = {"error": error} if error else {"image": f"renders/{job_id}.exr", "spp": spp, "seconds": took}
                self.items[name].update(stage=Stage.rendered, render=render)
                self.gs.update_item(self.id, name, stage=Stage.rendered, render=render)
                self.context.item_changed(self.id, name)

    def _take(self, job_id: str, variance: bool) -> None:
        """A finished job's image (and the reference's variance) into the run's folder: a hard link
        (no copy; the job's own file may go), or a copy where links are not allowed."""
        files = {JobFile.image_exr: f"{job_id}.exr"}
        if variance:
            files[JobFile.aov_floats] = f"{job_id}.variance.exr"
        (self.folder / "renders").mkdir(exist_ok=True)
        for kind, name in files.items():
            src, dst = self.store.job_file(job_id, kind), self.folder / "renders" / name
            if dst.exists():
                continue
            tmp = dst.with_name(f".{name}.tmp")
            tmp.unlink(missing_ok=True)
            try:
                os.link(src, tmp)
            except OSError:
                if not src.is_file():
                    raise
                shutil.copyfile(src, tmp)
            os.replace(tmp, dst)

    # -- tasks in the grading processes ---------------------------------------------------------

    def _schedule(self) -> None:
        for it in self.items.values():  # what a server stopped between two writes left undone
            if it["stage"] in (Stage.prepared, Stage.rendered) and (key := _key(it)) is not None:
                self._queue_render(key)
            if it["stage"] == Stage.prepared and not it["job_id"]:
                self._queue_item(it)
        if self.renders_total is None and all(it["stage"] != Stage.submitted for it in self.items.values()):
            students = sum(it["prepared"]["job"] is not None for it in self.items.values())
            self.renders_total = len(self.renders) + students
            self.gs.update_run(self.id, renders_total=self.renders_total)
        if self.suspects:  # after a process died: the tasks that were in flight, one at a time
            if not self.flight:
                for task, fn, kwargs in self._ready():
                    if task in self.suspects:
                        self.flight[self.pool.submit(fn, **kwargs())] = (task, True)
                        break
            return
        room = self.pool.processes * FLIGHT_PER_PROCESS - len(self.flight)
        for task, fn, kwargs in self._ready():
            if room <= 0:
                break
            self.flight[self.pool.submit(fn, **kwargs())] = (task, False)
            room -= 1

    def _ready(self) -> Iterator[tuple[tuple, Callable, Callable[[], dict]]]:
        """The tasks whose inputs are all there and that are not in flight, baselines first (many students
        wait for each): (task, function, its arguments when asked for)."""
        busy = {task for task, _ in self.flight.values()}
        mean = self.renders.get(MEAN)
        if mean is not None and mean["status"] == RenderStatus.done:
            wanted: dict[str, set[str]] = {}  # baseline -> the encodings of its students
            for it in self.items.values():
                if (key := _key(it)) is not None:
                    wanted.setdefault(key, set()).add(_encoding(it))
            for key, r in list(self.renders.items()):
                if key == MEAN or r["status"] == RenderStatus.waiting:
                    continue
                for enc in sorted(wanted.get(key, set()) - set(r["measured"])):
                    if r["status"] == RenderStatus.failed:  # nothing to measure: the students are told why
                        self._measured(key, enc, {"error": r["error"]})
                    elif ("baseline", key, enc) not in busy:
                        yield ("baseline", key, enc), tasks.measure_baseline, partial(self._baseline_args, r, enc)
        for s, it in self.items.items():
            if it["stage"] == Stage.submitted and ("prepare", s) not in busy:
                yield ("prepare", s), tasks.prepare_submission, partial(self._prepare_args, it)
        for s, it in self.items.items():
            if it["stage"] == Stage.rendered and ("metrics", s) not in busy and self._inputs_ready(it):
                yield ("metrics", s), tasks.grade_metrics, partial(self._metrics_args, it)

    def _prepare_args(self, it: dict) -> dict:
        return dict(assignment=self.text, student=it["student"], kind=it["kind"], path=str(self.folder / it["file"]),
                    filename=it["filename"])  # fmt: skip

    def _baseline_args(self, r: dict, enc: str) -> dict:
        fmt, bits = enc.split("/")
        baseline = {"image": str(self.folder / "renders" / f"{r['job_id']}.exr"), "spp": r["spp"]}
        return dict(assignment=self.text, reference=self._reference(), baseline=baseline, key=json.loads(r["key"]),
                    encoding=[fmt, int(bits)])  # fmt: skip

    def _inputs_ready(self, it: dict) -> bool:
        """Whether everything a student's image tests may need has ended (tracer.grading.finish_report's
        order: no tests or a problem found while preparing, then the reference, their render, the baseline)."""
        p = it["prepared"]
        if p["report"]["errors"] or not self.tests or p["report"]["metrics"].get("problem"):
            return True
        mean = self.renders.get(MEAN)
        if mean is None or mean["status"] == RenderStatus.waiting:
            return False
        if mean["status"] == RenderStatus.failed or (it["render"] or {}).get("error"):
            return True
        base = self.renders.get(_key(it))
        return base is not None and _encoding(it) in base["measured"]

    def _reference(self) -> dict:
        mean = self.renders.get(MEAN)
        if mean is None or mean["status"] == RenderStatus.waiting:
            return {}
        if mean["status"] == RenderStatus.failed:
            return {"error": mean["error"]}
        name = self.folder / "renders" / mean["job_id"]
        return {"mean": f"{name}.exr", "variance": f"{name}.variance.exr", "spp": mean["spp"]}

    def _metrics_args(self, it: dict) -> dict:
        p, render = it["prepared"], it["render"]
        if render and render.get("image"):
            render = {**render, "image": str(self.folder / render["image"])}
        base = self.renders.get(_key(it)) if _key(it) is not None else None
        return dict(
            assignment=self.text, prepared=p, out=str(self.folder / "out" / it["student"]),
            submission=str(self.folder / it["file"]), render=render, reference=self._reference(),
            baseline=base["measured"].get(_encoding(it)) if base else None,
        )  # fmt: skip

    def _collect(self, future: Future) -> None:
        task, alone = self.flight.pop(future)
        try:
            result = future.result()
        except BrokenProcessPool:
            if not alone:
                self.suspects.add(task)
                return
            self.breaks[task] = self.breaks.get(task, 0) + 1
            if self.breaks[task] < 2:
                return  # once more, alone (another run's task may have broken the pool this time)
            log.error("grading run %s: %s killed its grading process twice; it fails alone", self.id, task)
            self.suspects.discard(task)
            return self._failed(task, "its grading process died (twice; the server's log may say why)")
        except Exception as e:  # a bug, or a file the grading process could not read: this student alone fails
            if is_disk_full(e):  # not the student's: the run waits for space, and does the task again
                raise
            log.exception("grading run %s: %s failed", self.id, task)
            self.suspects.discard(task)
            return self._failed(task, f"grading error: {type(e).__name__}: {e}")
        self.suspects.discard(task)
        if task[0] == "prepare":
            self._prepared(task[1], result["prepared"], result["seconds"])
        elif task[0] == "baseline":
            self._measured(task[1], task[2], result)
        else:
            self._graded(task[1], result)

    def _prepared(self, student: str, p: dict, seconds: float | None) -> None:
        it = self.items[student]
        stage = Stage.prepared if p["job"] is not None else Stage.rendered
        it.update(prepared=p, stage=stage)
        it.pop("_key", None)
        self.gs.update_item(self.id, student, prepared=p, stage=stage, prepare_seconds=seconds)
        self.context.item_changed(self.id, student)
        if (key := _key(it)) is not None:
            self._queue_render(key)
        if p["job"] is not None:
            self._queue_item(it)

    def _measured(self, key: str, enc: str, metrics: dict) -> None:
        r = self.renders[key]
        r["measured"] = {**r["measured"], enc: metrics}
        self.gs.update_render(self.id, key, measured=r["measured"])

    def _graded(self, student: str, result: dict) -> None:
        row = result["row"]
        fields = dict(stage=Stage.graded, status=row["status"], score=result["score"], max_score=result["max_score"],
                      row=row, metrics_seconds=result["seconds"])  # fmt: skip
        self.items[student].update(fields)
        self.gs.update_item(self.id, student, **fields)
        self.context.item_changed(self.id, student)

    def _failed(self, task: tuple, message: str) -> None:
        """A task that could not be done: its student (or those of a baseline) is told why, and the run goes on."""
        if task[0] == "baseline":
            return self._measured(task[1], task[2], {"error": message})
        it = self.items[task[1]]
        if task[0] == "prepare":
            kind = "scene" if it["kind"] == "scene" else "image"
            blank = Prepared(Submission(it["student"], b"", it["kind"], it["filename"]),
                             Report(it["student"], self.grader.assignment.name, kind))  # fmt: skip
            return self._prepared(it["student"], self.grader.unreadable(blank, message).to_json(), None)
        p = Prepared.from_json(it["prepared"])  # the image tests: not compared, with the reason
        p.report.metrics["problem"] = message
        report = finish_report(self.grader.assignment, p, None, None, dict)
        write_report(self.folder / "out" / it["student"], report)
        self._graded(it["student"], {"row": summary_row(report), "score": report.score,
                                     "max_score": report.max_score, "seconds": None})  # fmt: skip


def _render_job(d: dict) -> RenderJob:
    return RenderJob(**{**d, "limits": Limits(**d["limits"])})
