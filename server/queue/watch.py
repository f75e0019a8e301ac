"""A render try's watch over the renderer's callbacks (server/queue/render_try.py): when to stop (`Stopped`, a
`Stop` reason), progress reports, previews, snapshots of the film, and a batch render giving way to interactive
work."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from server.jobs.files import JobFile
from server.jobs.lifecycle import Lane, Stop
from server.queue.channel import Channel
from server.queue.outputs import exr_bytes

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

    import numpy as np

CHECK_INTERVAL = 0.2  # seconds between two looks at the channel (cancel? still ours?) during a pass
PROGRESS_INTERVAL = 0.2  # seconds between two progress reports during a pass


class Watched(Protocol):
    """What a watch reads of its try (server/queue/render_try.py's Try), which it never imports."""

    job: Mapping[str, Any]
    channel: Channel
    stopping: Callable[[], bool]
    preview_interval: float
    snapshot_interval: float


class Stopped(Exception):
    """Raised from the band callback to end a render mid-pass; `reason` (a Stop) says why."""

    def __init__(self, reason: Stop):
        super().__init__(reason)
        self.reason = reason


@dataclass
class Pass:
    image: np.ndarray  # (H, W, 3) float32
    number: int
    spp: int
    rays: dict
    samples: int  # progress units done when it was taken


class Watch:
    """A render try's state between the renderer's callbacks: when to stop (`reason_to_stop`, looked at by
    `cancel` before each pass and by `on_band` after each band), progress reports, the previews published
    (`publish`), snapshots of the film, and giving way to interactive work (a batch render, `on_pass`)."""

    def __init__(self, try_: Watched, scene, cs, deadline: float):
        self.job, self.channel, self.stopping = try_.job, try_.channel, try_.stopping
        self.preview_interval, self.snapshot_interval = try_.preview_interval, try_.snapshot_interval
        self.scene, self.cs, self.deadline = scene, cs, deadline
        self.exposure = scene.film.exposure
        self.last: Pass | None = None  # the latest finished pass
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

    def publish(self, p: Pass) -> None:
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
        self.last = last = Pass(pr.image, pr.passes_done, pr.spp_done, pr.rays, done["samples"])
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
