"""The render worker: a separate process that takes jobs from the SQLite queue and renders them.

Started by the server (server/pool.py) with the "spawn" method, it loads the Warp kernels once,
then loops: claim the next job (priority, then age; an idle worker sleeps until the server signals
a submission, or `poll_interval` at most), render it pass by pass, and after each pass
write the running image (PNG for browsers, EXR with the linear floats) beside the job, atomically,
at most every `preview_interval` seconds. Only plain data crosses the process boundary: the job row
in SQLite, the settings as a dict, and the image files.

A job stops early when its row asks for cancellation, when it runs past its time limit, or when
the server shuts down (the job goes back to the queue). The check runs before each pass and,
between passes, after each band of rows, so a long pass is cut short too: the band callback raises
`Stop`, and the image of the last finished pass is the one kept.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import time
from dataclasses import dataclass

from server.channel import WorkerEnd
from server.lifecycle import JobStatus
from server.settings import Settings
from server.store import JobFile, JobStore

log = logging.getLogger("server.worker")

CHECK_INTERVAL = 0.2  # seconds between two looks at the job's row during a pass
PROGRESS_INTERVAL = 0.2  # seconds between two progress writes during a pass


class Stop(Exception):
    """Raised from the band callback to end a render mid-pass; `reason` says why."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def worker_main(settings_data: dict, conn) -> None:
    """Entry point of a worker process (spawned: it imports everything itself); `conn` is its end of
    the server's line (server/channel.py): wakes come in, "ready" goes out, end-of-file means stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group; the server stops us
    line = WorkerEnd(conn)
    settings = Settings(**settings_data)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s[%(process)d]: %(message)s")
    try:
        os.nice(settings.worker_nice)
    except OSError:
        pass
    load_kernels()
    line.ready()
    Worker(settings, JobStore(settings.data_dir), line.stopping).loop(line.wait)


def aov_pictures(aovs: dict) -> tuple[dict[str, bytes], dict[str, list[float]]]:
    """The renderer's AOVs as PNGs for the page, and each one's [min, max] (the legend of its colours).

    rays: rays traced per pixel as a heat map (black 0 ... red ... yellow ... white the maximum);
    depth: distance to the eye ray's hit as grey, near white to far dark grey, black where nothing was hit;
    normal: the shading normal as 0.5 + 0.5 n (no sRGB curve: the bytes are the vector);
    albedo: kd after texturing (sRGB like the image); variance: the mean of the RGB variance as a heat map."""
    import numpy as np

    from tracer.film import heat_map, png_bytes

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


def load_kernels() -> None:
    """Compile (or load from Warp's disk cache) the render kernels, once per process."""
    from tracer.render import load_kernels as load

    load("cpu")


@dataclass
class _Pass:
    image: object  # (H, W, 3) float32
    number: int
    spp: int
    rays: dict
    samples: int  # progress units done when it was taken


class Worker:
    """Claims and renders jobs; `stopping()` says the process should give its job back and exit."""

    def __init__(self, settings: Settings, store: JobStore, stopping, pid: int | None = None):
        self.settings, self.store, self.stopping = settings, store, stopping
        self.pid = pid or os.getpid()

    def loop(self, wait) -> None:
        log.info("render worker %d ready", self.pid)
        while not self.stopping():
            job = self.store.claim(self.pid)
            if job is None:
                wait(self.settings.poll_interval)
                continue
            self.run(job)
        log.info("render worker %d stopping", self.pid)

    def run(self, job: dict) -> None:
        job_id = job["id"]
        log.info("job %s: rendering (try %d)", job_id, job["attempts"])
        try:
            self._render(job)
        except Exception as exc:  # a bug or a broken scene must fail the job, not the worker
            log.exception("job %s failed", job_id)
            self.store.finish(job_id, self.pid, JobStatus.failed, error=f"render error: {type(exc).__name__}: {exc}")

    def _render(self, job: dict) -> None:
        from tracer.compile import compile_scene
        from tracer.film import png_bytes, write_exr
        from tracer.render import render
        from tracer.scene import SceneError, load_scene

        job_id, pid, store = job["id"], self.pid, self.store
        deadline = job["started_at"] + job["max_seconds"]
        try:
            scene, _ = load_scene(json.loads(job["scene"]), self.settings.limits)
            compiled = compile_scene(scene, solve_radiosity=False)  # render() solves radiosity, with progress
        except SceneError as exc:
            message = "; ".join(f"{e['path']}: {e['message']}" if e["path"] else e["message"] for e in exc.errors)
            store.finish(job_id, pid, JobStatus.failed, error=f"invalid scene: {message}", errors=exc.errors)
            return
        exposure = scene.film.exposure
        last: _Pass | None = None  # the latest finished pass
        published = 0  # number of the pass whose image is on disk
        clock = {"check": 0.0, "progress": 0.0, "preview": 0.0}
        done = {"samples": 0, "total": job["samples_total"]}  # the renderer's latest progress

        def reason_to_stop() -> str | None:
            if self.stopping():
                return "shutdown"
            if time.time() > deadline:
                return "timeout"
            row = store.control(job_id, pid)
            if row is None:
                return "lost"  # the job is no longer ours (the server gave it to another worker)
            if row["cancel_requested"]:
                return "cancel"
            return None

        def publish(p: _Pass) -> None:
            nonlocal published
            store.save_file(job_id, JobFile.image_png, png_bytes(p.image, exposure))
            store.save_file(job_id, JobFile.image_exr, lambda tmp: write_exr(tmp, p.image))
            published = p.number
            clock["preview"] = time.monotonic()

        def on_band(pr) -> None:  # after each band of a pass, and after each shot of a radiosity solve
            done.update(samples=pr.samples_done, total=pr.samples_total)
            now = time.monotonic()
            if pr.phase == "radiosity" and (now - clock["progress"] >= PROGRESS_INTERVAL or pr.solve["fraction"] >= 1):
                clock["progress"] = now
                store.progress(job_id, pid, solve=pr.solve)
            elif pr.phase != "radiosity" and now - clock["progress"] >= PROGRESS_INTERVAL:
                clock["progress"] = now
                store.progress(job_id, pid, samples_done=pr.samples_done, samples_total=pr.samples_total)
            if now - clock["check"] >= CHECK_INTERVAL:
                clock["check"] = now
                reason = reason_to_stop()
                if reason:
                    raise Stop(reason)

        def on_pass(pr) -> None:
            nonlocal last
            last = _Pass(pr.image, pr.passes_done, pr.spp_done, pr.rays, done["samples"])
            due = pr.passes_done == 1 or time.monotonic() - clock["preview"] >= self.settings.preview_interval
            if due and done["samples"] < done["total"]:  # the final image is published below
                publish(last)
            fields = dict(samples_done=done["samples"], samples_total=done["total"], passes_done=pr.passes_done)
            store.progress(job_id, pid, **fields, spp_done=pr.spp_done, rays=pr.rays, preview=published)

        stop_reason = None

        def cancel() -> bool:  # before each pass, and before each shot of a radiosity solve
            nonlocal stop_reason
            solving = scene.render.integrator == "radiosity" and compiled.radiosity is None
            if solving and time.monotonic() - clock["check"] < CHECK_INTERVAL:
                return False  # a solve's shots come every few ms: look at the row every CHECK_INTERVAL
            clock["check"] = time.monotonic()
            stop_reason = reason_to_stop()
            return stop_reason is not None

        try:
            result = render(
                compiled, threads=self.settings.threads_per_worker(), progress=on_band, cancel=cancel, on_pass=on_pass
            )
            if not result.cancelled:
                final = _Pass(result.image, last.number if last else 1, result.spp, result.rays, done["total"])
                publish(final)
                self._save_aovs(job_id, result.aovs)
                if compiled.radiosity is not None:
                    self._save_radiosity(job_id, compiled.radiosity)
                solved = {"solve": {**result.solve, "fraction": 1.0}} if result.solve else {}
                store.finish(
                    job_id, pid, JobStatus.done, samples_done=done["total"], samples_total=done["total"],
                    passes_done=final.number, spp_done=result.spp, rays=result.rays, preview=final.number, **solved,
                )  # fmt: skip
                log.info("job %s: done, %s", job_id, result.stats_line())
                return
        except Stop as stop:
            stop_reason = stop.reason
        self._stopped(job, stop_reason, last, published, publish)

    def _save_aovs(self, job_id: str, aovs: dict) -> None:
        """The AOV pictures of a finished render, beside its image (before the job is marked done)."""
        from tracer.film import aov_layers, write_exr

        try:
            pictures, ranges = aov_pictures(aovs)
            for name, png in pictures.items():
                self.store.save_file(job_id, JobFile.aov(name), png)
            self.store.save_file(job_id, JobFile.aov_ranges, json.dumps(ranges))
            layers = aov_layers(aovs)  # the floats too (the grader's variance), as EXR layers
            variance = layers.pop("variance")
            self.store.save_file(job_id, JobFile.aov_floats, lambda tmp: write_exr(tmp, variance, layers))
        except Exception:  # the image is what matters: a job never fails for its AOV pictures
            log.exception("job %s: could not save the AOV pictures", job_id)

    def _save_radiosity(self, job_id: str, solution) -> None:
        """A radiosity job's solution (patches, convergence, snapshots) for GET /api/jobs/{id}/radiosity."""
        try:
            self.store.save_file(job_id, JobFile.radiosity, json.dumps(solution.to_json()))
        except Exception:  # the image is what matters
            log.exception("job %s: could not save the radiosity solution", job_id)

    def _stopped(self, job: dict, reason: str | None, last: _Pass | None, published: int, publish) -> None:
        """End a render that stopped early: keep the last pass's image, then record why."""
        job_id, pid, store = job["id"], self.pid, self.store
        if reason == "lost":
            log.warning("job %s: no longer this worker's; dropped", job_id)
            return
        if reason == "shutdown":
            store.requeue(job_id, pid)
            log.info("job %s: back in the queue (worker stopping)", job_id)
            return
        if last is not None and published != last.number:
            publish(last)
        kept = {}
        if last is not None:
            kept = dict(passes_done=last.number, spp_done=last.spp, rays=last.rays, preview=last.number)
            kept["samples_done"] = last.samples
        if reason == "timeout":
            limit = job["max_seconds"]
            error = f"stopped: over the time limit of {limit:g} s per job (TRACER_MAX_JOB_SECONDS)"
            store.finish(job_id, pid, JobStatus.failed, error=error, **kept)
        else:
            store.finish(job_id, pid, JobStatus.cancelled, error="cancelled while rendering", **kept)
        log.info("job %s: stopped (%s)", job_id, reason)
