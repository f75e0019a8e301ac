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
from typing import TYPE_CHECKING, Any, Protocol

from server.core.files import is_disk_full
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobKind, JobStatus, Lane, Stop, TryEnd
from server.jobs.store import JobStore

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

    import numpy as np

    from tracer.radiosity.cache import SolutionCache
    from tracer.scene import Limits

log = logging.getLogger(__name__)

CHECK_INTERVAL = 0.2  # seconds between two looks at the channel (cancel? still ours?) during a pass
PROGRESS_INTERVAL = 0.2  # seconds between two progress reports during a pass


class Channel(Protocol):
    """Where a try reports (the job store here, or a worker host's Redis events)."""

    def stop_reason(self) -> Stop | None:
        """Stop.cancel (the job was cancelled), Stop.lost (it is no longer this try's), Stop.shutdown (the
        host asks for the job back), or None: go on."""
        ...

    def should_yield(self) -> bool:
        """Is interactive work waiting for this worker? (asked of a batch render at each pass)"""
        ...

    def snapshot(self) -> bytes | None:
        """The film this try continues from (a snapshot of an earlier try of the job), or None."""
        ...

    def progress(self, **fields) -> None:
        """Progress fields: samples_done, samples_total, passes_done, spp_done, rays, preview, solve,
        snapshot (the pass of the film just saved)."""

    def save(self, kind: JobFile, data: bytes | str) -> None:
        """One of the job's files, whole (it reaches the job's folder on the API host before the next
        progress or finish that follows it)."""

    def finish(self, status: JobStatus, **fields) -> None:
        """The try ended the job: done, failed or cancelled, with its last progress fields."""

    def give_back(self, outcome: TryEnd = TryEnd.given_back, **fields) -> None:
        """The job goes back to the queue: the host is shutting down (given back), or the render gives
        way to interactive work (gave way, its film saved just before)."""


class StoreChannel:
    """The embedded backend: a worker process on the API's host writes into the job store, fenced by
    its pid (a worker that lost its job can never write into the job's next life)."""

    def __init__(self, store: JobStore, job: Mapping[str, Any], pid: int):
        self.store, self.job, self.job_id, self.pid = store, job, job["id"], pid

    def stop_reason(self) -> Stop | None:
        row = self.store.control(self.job_id, self.pid)
        if row is None:
            return Stop.lost  # the job is no longer ours (the server gave it to another worker)
        return Stop.cancel if row["cancel_requested"] else None

    def should_yield(self) -> bool:
        return self.store.interactive_waiting()

    def snapshot(self) -> bytes | None:
        if not self.job.get("snapshot"):
            return None
        try:
            return self.store.job_file(self.job_id, JobFile.snapshot).read_bytes()
        except OSError:
            return None

    def progress(self, **fields) -> None:
        self.store.progress(self.job_id, self.pid, **fields)

    def save(self, kind: JobFile, data: bytes | str) -> None:
        self.store.save_file(self.job_id, kind, data)

    def finish(self, status: JobStatus, **fields) -> None:
        self.store.finish(self.job_id, self.pid, status, **fields)

    def give_back(self, outcome: TryEnd = TryEnd.given_back, **fields) -> None:
        if fields:
            self.store.progress(self.job_id, self.pid, **fields)
        self.store.requeue(self.job_id, self.pid, outcome)


def disk_full_error(exc: BaseException) -> str:
    """A job's error when its try met a full disk."""
    return f"stopped: the disk is full, so the job's images could not be kept ({exc}); submit it again later"


class Stopped(Exception):
    """Raised from the band callback to end a render mid-pass; `reason` (a Stop) says why."""

    def __init__(self, reason: Stop):
        super().__init__(reason)
        self.reason = reason


@dataclass
class _Pass:
    image: np.ndarray  # (H, W, 3) float32
    number: int
    spp: int
    rays: dict
    samples: int  # progress units done when it was taken


class _Watch:
    """A render try's state between the renderer's callbacks: when to stop (`reason_to_stop`, looked at by
    `cancel` before each pass and by `on_band` after each band), progress reports, the previews published
    (`publish`), snapshots of the film, and giving way to interactive work (a batch render, `on_pass`)."""

    def __init__(self, try_: Try, scene, cs, deadline: float):
        self.job, self.channel, self.stopping = try_.job, try_.channel, try_.stopping
        self.preview_interval, self.snapshot_interval = try_.preview_interval, try_.snapshot_interval
        self.scene, self.cs, self.deadline = scene, cs, deadline
        self.exposure = scene.film.exposure
        self.last: _Pass | None = None  # the latest finished pass
        self.published = 0  # number of the pass whose image is on disk
        self.clock = {"check": 0.0, "progress": 0.0, "preview": 0.0, "snapshot": time.monotonic()}
        self.done = {"samples": 0, "total": self.job["samples_total"]}  # the renderer's latest progress
        self.batch = self.job.get("lane") == Lane.batch
        params = self.job.get("params") or {}
        params = json.loads(params) if isinstance(params, str) else params
        self.lean = params.get("outputs") == "floats"  # grading: only the final image and its floats
        self.stop_reason: Stop | None = None

    def reason_to_stop(self) -> Stop | None:
        if self.stopping():
            return Stop.shutdown
        if time.time() > self.deadline:
            return Stop.timeout
        return self.channel.stop_reason()

    def publish(self, p: _Pass) -> None:
        """The pass's image on disk: PNG (with the scene's exposure) and EXR."""
        from tracer.rendering.film import png_bytes

        self.channel.save(JobFile.image_png, png_bytes(p.image, self.exposure))
        self.channel.save(JobFile.image_exr, exr_bytes(p.image))
        self.published = p.number
        self.clock["preview"] = time.monotonic()

    def on_band(self, pr) -> None:
        """After each band of a pass, and after each shot of a radiosity solve: progress, and the stop check."""
        clock = self.clock
        self.done.update(samples=pr.samples_done, total=pr.samples_total)
        now = time.monotonic()
        if pr.phase == "radiosity" and (now - clock["progress"] >= PROGRESS_INTERVAL or pr.solve["fraction"] >= 1):
            clock["progress"] = now
            self.channel.progress(solve=pr.solve)
        elif pr.phase != "radiosity" and now - clock["progress"] >= PROGRESS_INTERVAL:
            clock["progress"] = now
            self.channel.progress(samples_done=pr.samples_done, samples_total=pr.samples_total)
        if now - clock["check"] >= CHECK_INTERVAL:
            clock["check"] = now
            reason = self.reason_to_stop()
            if reason:
                raise Stopped(reason)

    def on_pass(self, pr) -> None:
        """After each pass: a preview when one is due, progress, a snapshot now and then; a batch render gives
        way here when the channel asks it to."""
        from tracer.rendering.progressive import snapshot_bytes

        channel, clock, done = self.channel, self.clock, self.done
        self.last = last = _Pass(pr.image, pr.passes_done, pr.spp_done, pr.rays, done["samples"])
        due = pr.passes_done == 1 or time.monotonic() - clock["preview"] >= self.preview_interval
        final = done["samples"] >= done["total"]
        if due and not final and not self.lean:  # the final image is published by Try._done
            self.publish(last)
        fields = dict(samples_done=done["samples"], samples_total=done["total"], passes_done=pr.passes_done)
        fields.update(spp_done=pr.spp_done, rays=pr.rays, preview=self.published)
        if not final and time.monotonic() - clock["snapshot"] >= self.snapshot_interval:
            channel.save(JobFile.snapshot, snapshot_bytes(pr.snapshot()))  # a later try continues from here
            fields["snapshot"] = pr.passes_done
            clock["snapshot"] = time.monotonic()
        channel.progress(**fields)
        if self.batch and not final and channel.should_yield():
            if self.published != last.number:
                self.publish(last)
            channel.save(JobFile.snapshot, snapshot_bytes(pr.snapshot()))
            raise Stopped(Stop.give_way)

    def cancel(self) -> bool:
        """Before each pass, and before each shot of a radiosity solve: whether to stop (the reason kept)."""
        solving = self.scene.render.integrator_info.prepass == "radiosity" and self.cs.radiosity is None
        if solving and time.monotonic() - self.clock["check"] < CHECK_INTERVAL:
            return False  # a solve's shots come every few ms: look at the channel every CHECK_INTERVAL
        self.clock["check"] = time.monotonic()
        self.stop_reason = self.reason_to_stop()
        return self.stop_reason is not None


def aov_pictures(aovs: dict) -> tuple[dict[str, bytes], dict[str, list[float]]]:
    """The renderer's AOVs as PNGs for the page, and each one's [min, max] (the legend of its colours).

    rays: rays traced per pixel as a heat map (black 0 ... red ... yellow ... white the maximum);
    depth: distance to the eye ray's hit as grey, near white to far dark grey, black where nothing was hit;
    normal: the shading normal as 0.5 + 0.5 n (no sRGB curve: the bytes are the vector);
    albedo: kd after texturing (sRGB like the image); variance: the mean of the RGB variance as a heat map."""
    import numpy as np

    from tracer.rendering.film import heat_map, png_bytes

    out: dict[str, bytes] = {}
    ranges: dict[str, list[float]] = {}

    def span(name: str, values: np.ndarray) -> None:
        finite = values[np.isfinite(values)]
        ranges[name] = [float(finite.min()), float(finite.max())] if finite.size else [0.0, 0.0]

    if "rays" in aovs:
        rays = np.nan_to_num(aovs["rays"])
        span("rays", rays)
        out["rays"] = png_bytes(heat_map(rays))
    if "depth" in aovs:
        depth = np.nan_to_num(aovs["depth"], posinf=0.0)
        hit = depth > 0
        far = float(depth.max()) if hit.any() else 1.0
        span("depth", depth[hit] if hit.any() else depth)
        out["depth"] = png_bytes(np.where(hit, 1.0 - 0.85 * depth / far, 0.0), srgb=False)
    if "normal" in aovs:
        normal = np.nan_to_num(aovs["normal"])
        span("normal", normal)
        out["normal"] = png_bytes(0.5 + 0.5 * normal, srgb=False)
    if "albedo" in aovs:
        albedo = np.nan_to_num(aovs["albedo"])
        span("albedo", albedo)
        out["albedo"] = png_bytes(albedo)
    if "variance" in aovs:
        variance = np.nan_to_num(aovs["variance"]).mean(axis=-1)
        span("variance", variance)
        out["variance"] = png_bytes(heat_map(variance))
    return out, ranges


def exr_bytes(image, layers: dict | None = None) -> bytes:
    """An EXR file's bytes (tracer.rendering.film.write_exr writes files: through a temporary one)."""
    import tempfile
    from pathlib import Path

    from tracer.rendering.film import write_exr

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "image.exr"
        write_exr(path, image, layers)
        return path.read_bytes()


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
        when there is one) with a _Watch over them; the try ends done, giving way, or stopped."""
        from tracer.rendering.progressive import render

        deadline = time.time() + self.job["max_seconds"]  # the compile counts too
        compiled = self._scene()
        if compiled is None:
            return TryEnd.failed
        scene, cs = compiled
        watch = _Watch(self, scene, cs, deadline)
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

    def _done(self, watch: _Watch, cs, result) -> TryEnd:
        """A finished render: its final image, AOVs and radiosity solution saved, then the job done."""
        done = watch.done
        final = _Pass(result.image, watch.last.number if watch.last else 1, result.spp, result.rays, done["total"])
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

    def _gave_way(self, watch: _Watch) -> TryEnd:
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

    def _stopped(self, reason: Stop | None, last: _Pass | None, published: int, publish) -> Stop:
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
