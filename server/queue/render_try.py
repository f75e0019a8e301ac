"""One try of one job: render it pass by pass and report through a channel, whichever host it runs on.

Both queue backends run a job this way. The embedded backend's worker processes (server/queue/embedded/worker.py)
report straight into the job store on this host (`StoreChannel`); a worker host of the Redis backend
(server/queue/redis/host.py) reports into Redis, and the API applies what it sends to its store
(server/queue/redis/queue.py). So a job behaves the same wherever it renders: progress after each band,
the running image (PNG for browsers, EXR with the linear floats) after a pass at most every
`preview_interval` seconds, and at the end the final image, the AOV pictures and floats, and a
radiosity job's solution.

A try stops early when its channel says the job is cancelled or no longer this try's, when it runs
past its time limit, or when its host shuts down (the job goes back to the queue). The check runs
before each pass and, during a pass, after each launch (tracer/rendering/progressive.py cuts a pass into launches of
about a quarter of a second, none past a bound on its rays), so a long pass is cut short too, within
about a second: the band callback raises `Stopped`, and the image of the last finished pass is the one
kept. A ray tree is one launch of one sample, whose rays the scene's bound on a tree keeps few.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from server.core.files import is_disk_full
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobKind, JobStatus, Stop, TryEnd
from server.queue.channel import Channel
from server.queue.outputs import aov_pictures, exr_bytes
from server.queue.watch import CHECK_INTERVAL, Pass, Stopped, Watch

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

    from tracer.radiosity.cache import SolutionCache
    from tracer.scene import Limits

log = logging.getLogger(__name__)


def disk_full_error(exc: BaseException) -> str:
    """A job's error when its try met a full disk."""
    return f"stopped: the disk is full, so the job's images could not be kept ({exc}); submit it again later"


@dataclass
class Try:
    """One try of a job. `job`: id, kind, lane, params, scene (JSON text), max_seconds, samples_total,
    attempts and snapshot, as the store's row has them (params: a ray tree's pixel; a render's `outputs`,
    "floats" for grading: no previews and no AOV pictures, only the final image and the AOVs' floats);
    `limits`: the scene limits; `stopping()`: the host is shutting down; `cache`: radiosity solutions by
    content (a radiosity.SolutionCache); `snapshot_interval`: seconds of rendering between two snapshots of the film."""

    job: Mapping[str, Any]  # a job's row (embedded), or the try's payload (a Redis worker host)
    channel: Channel
    limits: Limits
    threads: int
    preview_interval: float
    stopping: Callable[[], bool]
    device: str = "cpu"
    cache: SolutionCache | None = None
    snapshot_interval: float = 10.0

    def run(self) -> TryEnd | Stop:
        """Run the try to its end; returns how it ended: TryEnd.done or .failed, TryEnd.gave_way, or the
        Stop that ended it (cancel, timeout, shutdown, lost)."""
        from tracer.scene import SceneError

        job_id = self.job["id"]
        try:
            if self.job.get("kind", JobKind.render) == JobKind.raytree:
                return self._raytree()
            return self._render()
        except SceneError as exc:  # past a limit only the compiled scene shows (a radiosity solve's patches)
            self._invalid(exc)
            return TryEnd.failed
        except Exception as exc:  # a bug or a broken scene must fail the job, not the worker
            if is_disk_full(exc):  # not a bug: said plainly (a finish that cannot be written raises to the worker)
                log.warning("job %s: %s", job_id, disk_full_error(exc))
                self.channel.finish(JobStatus.failed, error=disk_full_error(exc))
                return TryEnd.failed
            log.exception("job %s failed", job_id)
            self.channel.finish(JobStatus.failed, error=f"render error: {type(exc).__name__}: {exc}")
            return TryEnd.failed

    def _scene(self):
        """The job's scene, validated and compiled; None (the job failed, with its errors) if it is not."""
        from tracer.kernels.compile import compile_scene
        from tracer.scene import SceneError, load_scene

        try:
            scene, _ = load_scene(json.loads(self.job["scene"]), self.limits)
            return scene, compile_scene(scene, device=self.device, limits=self.limits)
        except SceneError as exc:
            self._invalid(exc)
            return None

    def _invalid(self, exc) -> None:
        """The job failed for its scene's errors (a SceneError's), each at its path."""
        message = "; ".join(f"{e['path']}: {e['message']}" if e["path"] else e["message"] for e in exc.errors)
        self.channel.finish(JobStatus.failed, error=f"invalid scene: {message}", errors=exc.errors)

    def _raytree(self) -> TryEnd | Stop:
        """A ray tree: one pixel sample traced with its rays recorded (a radiosity scene's solution from
        the cache after the first click)."""
        from tracer import radiosity
        from tracer.radiosity.solver import Solution
        from tracer.rendering.raytree import ray_tree
        from tracer.scene import SceneError

        compiled = self._scene()
        if compiled is None:
            return TryEnd.failed
        scene, cs = compiled
        params = self.job.get("params") or {}
        params = json.loads(params) if isinstance(params, str) else params
        if scene.render.integrator_info.prepass == "radiosity":  # the solve (once per scene, then cached) may stop
            if self._solve_too_long(cs, params):
                return TryEnd.failed
            deadline, clock = time.time() + self.job["max_seconds"], {"check": 0.0}
            stop: dict = {}

            def cancel() -> bool:
                if time.monotonic() - clock["check"] < CHECK_INTERVAL:
                    return False
                clock["check"] = time.monotonic()
                stop["why"] = Stop.timeout if time.time() > deadline else self.channel.stop_reason()
                return stop["why"] is not None

            try:
                radiosity.attach(cs, device=self.device, threads=self.threads, cancel=cancel, cache=self.cache)
            except radiosity.Cancelled:
                if stop["why"] is Stop.timeout:
                    limit = self.job["max_seconds"]
                    error = f"stopped: the radiosity solve took longer than the ray tree's limit of {limit:g} s"
                    self.channel.finish(JobStatus.failed, error=error)
                elif stop["why"] is Stop.cancel:
                    self.channel.finish(JobStatus.cancelled, error="cancelled while solving")
                elif stop["why"] is Stop.shutdown:
                    self.channel.give_back()
                return stop["why"]
        try:
            tree = ray_tree(cs, int(params["x"]), int(params["y"]), int(params.get("sample", 0)), device=self.device)
        except SceneError as exc:
            self.channel.finish(JobStatus.failed, error="; ".join(e["message"] for e in exc.errors), errors=exc.errors)
            return TryEnd.failed
        self.channel.save(JobFile.raytree, json.dumps(tree))
        solved = {"solve": {**cs.radiosity.stats(), "fraction": 1.0}} if isinstance(cs.radiosity, Solution) else {}
        self.channel.finish(JobStatus.done, samples_done=1, samples_total=1, passes_done=1, spp_done=1, **solved)
        return TryEnd.done

    def _solve_too_long(self, cs, params: dict) -> bool:
        """A ray tree whose radiosity solve is not in the cache, and is estimated (by the API, `solve_seconds`
        in its params) past the ray tree's time limit, is refused before the solve starts: the job fails with
        an error at render.radiosity. A solution in the cache is already paid for."""
        estimate, limit = float(params.get("solve_seconds") or 0), self.job["max_seconds"]
        if estimate <= limit or (self.cache is not None and self.cache.has(self.cache.key(cs))):
            return False
        message = (
            f"the radiosity solve would take about {estimate:.0f} s here, past the ray tree's limit of {limit:g} s "
            "(TRACER_MAX_RAYTREE_SECONDS): render the scene first (its solution is kept, and the ray trees of the "
            "scene then use it), or use a larger patch_size, fewer rays or a larger threshold"
        )
        errors = [{"path": "render.radiosity", "message": message}]
        self.channel.finish(JobStatus.failed, error=message, errors=errors)
        return True

    def _resume_from(self) -> dict | None:
        """The film of an earlier try of this job, if it left one the row knows of (else from the start)."""
        from tracer.rendering.progressive import snapshot_from

        want = int(self.job.get("snapshot") or 0)
        data = self.channel.snapshot() if want else None
        if not data:
            return None
        try:
            snap = snapshot_from(data)
        except Exception:  # a broken file: render from the start
            log.warning("job %s: its snapshot could not be read; rendering from the start", self.job["id"])
            return None
        return snap if snap["passes"] == want else None

    def _render(self) -> TryEnd | Stop:
        """A render: the scene compiled, then the renderer's passes (continuing from an earlier try's film
        when there is one) with a Watch over them; the try ends done, giving way, or stopped."""
        from tracer.rendering.progressive import render

        deadline = time.time() + self.job["max_seconds"]  # the compile counts too
        compiled = self._scene()
        if compiled is None:
            return TryEnd.failed
        scene, cs = compiled
        watch = Watch(self, scene, cs, deadline)
        resume = self._resume_from()
        if resume is not None:
            watch.published = int(self.job.get("preview") or 0)
            log.info("job %s: continuing from pass %d", self.job["id"], resume["passes"])
        try:
            result = render(
                cs, threads=self.threads, progress=watch.on_band, cancel=watch.cancel, on_pass=watch.on_pass,
                device=self.device, radiosity_cache=self.cache, resume=resume,
            )  # fmt: skip
            if not result.cancelled:
                return self._done(watch, cs, result)
        except Stopped as stop:
            watch.stop_reason = stop.reason
        if watch.stop_reason is Stop.give_way:
            return self._gave_way(watch)
        return self._stopped(watch.stop_reason, watch.last, watch.published, watch.publish)

    def _done(self, watch: Watch, cs, result) -> TryEnd:
        """A finished render: its final image, AOVs and radiosity solution saved, then the job done."""
        done = watch.done
        final = Pass(result.image, watch.last.number if watch.last else 1, result.spp, result.rays, done["total"])
        watch.publish(final)
        self._save_aovs(result.aovs, pictures=not watch.lean)
        if cs.radiosity is not None:
            self._save_radiosity(cs.radiosity)
        solved = {"solve": {**result.solve, "fraction": 1.0}} if result.solve else {}
        self.channel.finish(
            JobStatus.done, samples_done=done["total"], samples_total=done["total"],
            passes_done=final.number, spp_done=result.spp, rays=result.rays, preview=final.number, **solved,
        )  # fmt: skip
        log.info("job %s: done, %s", self.job["id"], result.stats_line())
        return TryEnd.done

    def _gave_way(self, watch: Watch) -> TryEnd:
        """A batch render that gave way to interactive work: back in the queue, to continue from its snapshot."""
        assert watch.last is not None  # it gives way only at the end of a pass (on_pass)
        self.channel.give_back(TryEnd.gave_way, snapshot=watch.last.number, preview=watch.published)
        log.info("job %s: gave way to interactive work after pass %d", self.job["id"], watch.last.number)
        return TryEnd.gave_way

    def _save_aovs(self, aovs: dict, pictures: bool = True) -> None:
        """The AOV pictures of a finished render (unless `pictures` is False: a grading render, whose
        pictures nobody looks at), and their floats, beside its image (before the job is marked done)."""
        from tracer.rendering.film import aov_layers

        try:
            if pictures:
                pngs, ranges = aov_pictures(aovs)
                for name, png in pngs.items():
                    self.channel.save(JobFile.aov(name), png)
                self.channel.save(JobFile.aov_ranges, json.dumps(ranges))
            layers = aov_layers(aovs)  # the floats too (the grader's variance), as EXR layers
            variance = layers.pop("variance")
            self.channel.save(JobFile.aov_floats, exr_bytes(variance, layers))
        except Exception:  # the image is what matters: a job never fails for its AOV pictures
            log.exception("job %s: could not save the AOV pictures", self.job["id"])

    def _save_radiosity(self, solution) -> None:
        """A radiosity job's solution (patches, convergence, snapshots) for GET /api/jobs/{id}/radiosity."""
        try:
            self.channel.save(JobFile.radiosity, json.dumps(solution.to_json()))
        except Exception:  # the image is what matters
            log.exception("job %s: could not save the radiosity solution", self.job["id"])

    def _stopped(self, reason: Stop | None, last: Pass | None, published: int, publish) -> Stop:
        """End a render that stopped early: keep the last pass's image, then record why."""
        job, channel = self.job, self.channel
        if reason is Stop.lost:
            log.warning("job %s: no longer this try's; dropped", job["id"])
            return Stop.lost
        if reason is Stop.shutdown:
            channel.give_back()
            log.info("job %s: back in the queue (worker stopping)", job["id"])
            return Stop.shutdown
        if last is not None and published != last.number:
            publish(last)
        kept = {}
        if last is not None:
            kept = dict(passes_done=last.number, spp_done=last.spp, rays=last.rays, preview=last.number)
            kept["samples_done"] = last.samples
        if reason is Stop.timeout:
            limit = job["max_seconds"]
            error = f"stopped: over the time limit of {limit:g} s per job (TRACER_MAX_JOB_SECONDS)"
            channel.finish(JobStatus.failed, error=error, **kept)
        else:
            channel.finish(JobStatus.cancelled, error="cancelled while rendering", **kept)
        log.info("job %s: stopped (%s)", job["id"], reason)
        return reason or Stop.cancel
