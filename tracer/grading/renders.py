"""The renders a grade needs, as plain data, and the renderer that makes them in this process.

A renderer is a callable that takes a list of RenderJobs and returns one Rendered each, in order.
`InlineRenderer` renders here, one after another; the CLI's worker processes (local.py) and the service's
job queue (server/grading/runs.py) render them elsewhere, with a time limit per job.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from tracer.grading.report import error_text
from tracer.scene import Limits, SceneError, load_scene


@dataclass
class RenderJob:
    """One render the grader needs, as plain data (it may cross a process boundary)."""

    name: str  # who it is for: a student, "reference", "baseline 4 spp jittered"
    scene: dict  # the scene JSON, settings already applied
    max_seconds: float  # stopped (an error) past this
    limits: Limits = field(default_factory=Limits)
    priority: int = 0  # higher first (the reference renders go before the students')
    limit_source: str = "the assignment's limits.max_seconds"  # what set max_seconds, for the message


def over_time(seconds: float, source: str) -> str:
    """Why a render has no image: it ran past its time limit, and what set that limit."""
    return f"stopped: over the time limit of {seconds:g} s per render (set by {source})"


@dataclass
class Rendered:
    image: np.ndarray | None = None  # (H, W, 3) float32 linear radiance
    variance: np.ndarray | None = None  # (H, W, 3) the samples' variance
    spp: int = 0
    seconds: float = 0.0
    error: str | None = None  # why there is no image


Renderer = Callable[[list[RenderJob]], list[Rendered]]


class InlineRenderer:
    """Renders in this process, one job after another (each over `threads`); a job past its
    `max_seconds` is stopped at the next pass and counts as an error."""

    def __init__(self, threads: int | None = None):
        self.threads = threads

    def __call__(self, jobs: list[RenderJob]) -> list[Rendered]:
        return [self.one(job) for job in jobs]

    def one(self, job: RenderJob) -> Rendered:
        from tracer.kernels.compile import compile_scene
        from tracer.rendering.progressive import render

        start = time.monotonic()
        try:
            scene, _ = load_scene(job.scene, job.limits)
            result = render(
                compile_scene(scene, limits=job.limits), threads=self.threads,
                cancel=lambda: time.monotonic() - start > job.max_seconds,
            )  # fmt: skip
        except SceneError as e:
            return Rendered(error="invalid scene: " + "; ".join(error_text(x) for x in e.errors))
        if result.cancelled:
            return Rendered(error=over_time(job.max_seconds, job.limit_source))
        return Rendered(result.image, result.aovs["variance"], result.spp, time.monotonic() - start)
