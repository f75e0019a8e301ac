"""A grading run's render jobs (server/grading/run.py says how a run goes): the class's renders (the reference mean,
the noise baselines) and each student's queued like any other job, polled, and their images taken into the run's
folder (renders/<job>.exr), so that the janitor may remove a job from then on.

A resumed run finds a render job it had queued by its id (still queued or running: waited for; finished: its
image taken, never rendered again); only a job that is gone (the janitor removed it before the run took its
image), or one that failed because the disk was full, is queued again.
"""

from __future__ import annotations

import json
import logging
import os
import shutil

from server.core.files import is_disk_full
from server.grading.renders import capped, job_outcome
from server.grading.run_base import MEAN, RunBase, RunItem
from server.grading.store import RenderStatus, Stage
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, Lane
from tracer.grading import RenderJob
from tracer.scene import Limits, SceneError, load_scene

log = logging.getLogger(__name__)

MAX_QUEUED = 1_000_000  # a class is queued whole: the queue's limit (TRACER_MAX_QUEUED_JOBS) is for students
JOB_DISK_FULL = "the disk is full"  # in the error of a render job that failed for it (server/queue/render_try.py)


class RunRenders(RunBase):
    """The render jobs of a run (a mixin of GradingRun, server/grading/run.py)."""

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
            r = self.renders[key] = {"run_id": self.id, "key": key, "job_id": None, "status": RenderStatus.waiting,
                                     "spp": None, "seconds": None, "error": None, "measured": {}}  # fmt: skip
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

    def _queue_item(self, it: RunItem) -> None:
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


def _render_job(d: dict) -> RenderJob:
    return RenderJob(**{**d, "limits": Limits(**d["limits"])})
