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

Its parts: run_base.py (the RunContext its runs hand it, its state), run_renders.py (the render jobs),
run_tasks.py (the tasks in the grading processes, at most FLIGHT_PER_PROCESS per process in flight); this
module drives them.
"""

from __future__ import annotations

import logging
from concurrent.futures import FIRST_COMPLETED, wait
from typing import cast

from server.core.files import is_disk_full
from server.grading.run_base import MEAN, RunItem
from server.grading.run_tasks import RunTasks
from server.grading.store import Stage
from server.jobs.lifecycle import JobStatus
from tracer.grading import Grader, load_assignment
from tracer.grading.batch import class_summary, write_summary

log = logging.getLogger(__name__)

POLL = 0.2  # seconds between two looks at the run's render jobs
IDLE = 1.0  # seconds between two looks whether the server stops, for an open run with nothing to do
SPACE_RETRY = 30.0  # seconds a run that met a full disk waits before it tries again (the janitor wakes it sooner)


class GradingRun(RunTasks):
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
        self.items = {it["student"]: cast(RunItem, it) for it in self.gs.items(self.id)}
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
            self.items.update({it["student"]: cast(RunItem, it) for it in new})
            self.renders_total = None  # counted again once they are prepared

    def _finish(self) -> None:
        items = sorted(self.items.values(), key=lambda it: it["position"])
        rows = [it["row"] for it in items]
        scores = cast(list[tuple[float, float]], [(it["score"], it["max_score"]) for it in items])  # all graded
        table = class_summary(self.grader.assignment.name if rows else None, rows, scores)
        (self.folder / "out").mkdir(parents=True, exist_ok=True)
        write_summary(self.folder / "out", table)
        self.gs.end_run(self.id, JobStatus.done, summary=table)
        log.info("grading run %s: done, %d students", self.id, len(rows))
