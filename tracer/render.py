"""Rendering: progressive passes over bands of rows, launched from a thread pool.

A Warp CPU launch runs on one thread and releases the GIL, so bands of rows are launched
from one Python thread per core. Each pixel's samples are added in sample order by a single
thread into a float accumulation buffer, so the image is bit-identical for any thread count,
band size or split of the samples into passes (the RNG is keyed by seed, pixel and sample).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from tracer.compile import CompiledScene, compile_scene
from tracer.integrators import dispatch, record, whitted
from tracer.kinds import RayKind
from tracer.scene import Scene

BAND_PIXELS = 4096  # pixels per launch: small enough to balance two threads, large enough to amortise


def make_stack(rows: int, depth: int, device: str = "cpu") -> whitted.Stack:
    st = whitted.Stack()
    shape = (rows, depth + 1)
    st.o = wp.empty(shape, dtype=wp.vec3, device=device)
    st.d = wp.empty(shape, dtype=wp.vec3, device=device)
    st.k = wp.empty(shape, dtype=wp.vec3, device=device)
    st.w = wp.empty(shape, dtype=wp.vec3, device=device)
    st.tau = wp.empty(shape, dtype=wp.vec3, device=device)
    st.i = wp.empty(shape, dtype=wp.vec3i, device=device)
    return st


def make_record(cap: int, device: str = "cpu") -> record.TreeRecord:
    rec = record.TreeRecord()
    rec.cap = cap
    rec.count = wp.zeros(1, dtype=wp.int32, device=device)
    rec.ints = wp.zeros((max(cap, 1), record.NUM_I), dtype=wp.int32, device=device)
    rec.vecs = wp.zeros((max(cap, 1), record.NUM_V), dtype=wp.vec3, device=device)
    rec.floats = wp.zeros((max(cap, 1), record.NUM_F), dtype=wp.float32, device=device)
    return rec


def make_film(height: int, width: int, device: str = "cpu") -> dispatch.FilmBuffers:
    f = dispatch.FilmBuffers()
    shape = (height, width)
    f.accum = wp.zeros(shape, dtype=wp.vec3, device=device)
    f.sumsq = wp.zeros(shape, dtype=wp.vec3, device=device)
    f.counts = wp.zeros(shape, dtype=wp.vec4i, device=device)
    f.depth = wp.zeros(shape, dtype=float, device=device)
    f.normal = wp.zeros(shape, dtype=wp.vec3, device=device)
    f.albedo = wp.zeros(shape, dtype=wp.vec3, device=device)
    return f


def load_kernels(device: str = "cpu") -> None:
    """Compile the render kernels, or load them from Warp's disk cache (call before threads start)."""
    wp.load_module(dispatch, device=device)


def default_threads() -> int:
    return max(1, os.cpu_count() or 1)


@dataclass
class Progress:
    """What a progress callback sees after each band of each pass."""

    samples_done: int  # pixel samples finished so far
    samples_total: int
    passes_done: int
    elapsed: float  # seconds


@dataclass
class RenderResult:
    image: np.ndarray  # (H, W, 3) float32 linear radiance, the mean of the samples
    spp: int  # samples per pixel in `image`
    seconds: float
    rays: dict = field(default_factory=dict)  # rays by kind name, and "total"
    cancelled: bool = False
    aovs: dict = field(default_factory=dict)  # name -> (H, W) or (H, W, 3) float32, see Renderer.aovs

    def stats_line(self) -> str:
        total = self.rays.get("total", 0)
        kinds = " ".join(f"{k}={v}" for k, v in self.rays.items() if k != "total")
        mrays = total / self.seconds / 1e6 if self.seconds > 0 else 0.0
        return f"{self.seconds:.2f} s, {total} rays ({kinds}), {mrays:.2f} Mrays/s"


def pass_schedule(spp: int) -> list[tuple[int, int]]:
    """Sample ranges of the progressive passes: 1, 1, 2, 4, ... samples per pixel."""
    passes, s0, n = [], 0, 1
    while s0 < spp:
        s1 = min(spp, s0 + n)
        passes.append((s0, s1))
        if s0 > 0:
            n *= 2
        s0 = s1
    return passes


class Renderer:
    """A compiled scene with its accumulation buffers; `run` adds passes until spp is reached."""

    def __init__(self, compiled: CompiledScene, threads: int | None = None, device: str = "cpu"):
        self.cs = compiled
        self.device = device
        load_kernels(device)
        data = compiled.data
        self.width, self.height, self.spp = data.width, data.height, data.spp
        self.threads = threads or default_threads()
        self.rows_per_band = max(1, BAND_PIXELS // self.width)
        self.film = make_film(self.height, self.width, device)
        band = self.rows_per_band * self.width
        self.stacks = [make_stack(band, data.max_depth, device) for _ in range(self.threads)]
        self.dummy = make_record(0, device)
        self.samples_done = 0  # per pixel

    def _band(self, worker: int, y0: int, s0: int, s1: int) -> None:
        n = min(self.rows_per_band, self.height - y0) * self.width
        wp.launch(
            dispatch.render_rows,
            dim=n,
            device=self.device,
            inputs=[self.cs.data, y0, s0, s1, self.stacks[worker], self.dummy, self.film],
        )

    def add_samples(self, s0: int, s1: int, on_band: Callable[[int], None] | None = None) -> None:
        """Trace samples s0..s1-1 of every pixel (bands spread over the thread pool)."""
        bands = list(range(0, self.height, self.rows_per_band))
        if self.threads == 1:
            for y0 in bands:
                self._band(0, y0, s0, s1)
                if on_band:
                    on_band(min(self.rows_per_band, self.height - y0) * self.width)
        else:
            queue = iter(bands)
            lock = threading.Lock()

            def worker(k: int) -> None:
                while True:
                    with lock:
                        y0 = next(queue, None)
                    if y0 is None:
                        return
                    self._band(k, y0, s0, s1)
                    if on_band:
                        with lock:
                            on_band(min(self.rows_per_band, self.height - y0) * self.width)

            with ThreadPoolExecutor(self.threads) as pool:
                for f in [pool.submit(worker, k) for k in range(self.threads)]:
                    f.result()
        wp.synchronize_device(self.device)
        self.samples_done = s1

    def image(self) -> np.ndarray:
        """The mean of the samples so far, (H, W, 3) float32."""
        acc = self.film.accum.numpy()
        return (acc / max(self.samples_done, 1)).astype(np.float32)

    def aovs(self) -> dict[str, np.ndarray]:
        """Arbitrary output variables, averaged over the samples so far (float32):
        depth (H, W): distance to the eye ray's hit, 0 where it left the scene; normal (H, W, 3): the
        shading normal there; albedo (H, W, 3): kd there; rays (H, W): rays traced for the pixel,
        all kinds; variance (H, W, 3): the samples' variance (unbiased, per channel)."""
        n = max(self.samples_done, 1)
        mean = self.film.accum.numpy() / n
        var = (self.film.sumsq.numpy() / n - mean * mean) * (n / max(n - 1, 1))
        return {
            "depth": (self.film.depth.numpy() / n).astype(np.float32),
            "normal": (self.film.normal.numpy() / n).astype(np.float32),
            "albedo": (self.film.albedo.numpy() / n).astype(np.float32),
            "rays": self.film.counts.numpy().sum(axis=-1).astype(np.float32),
            "variance": np.maximum(var, 0.0).astype(np.float32),
        }

    def rays(self) -> dict:
        c = self.film.counts.numpy().reshape(-1, 4).astype(np.int64).sum(axis=0)
        out = {k.name.lower(): int(c[k]) for k in RayKind}
        out["total"] = int(c.sum())
        return out


@dataclass
class PassResult:
    """What an `on_pass` callback sees after each progressive pass: the running image."""

    image: np.ndarray  # (H, W, 3) float32, the mean of the samples so far
    spp_done: int  # samples per pixel in `image`
    spp_total: int
    passes_done: int
    elapsed: float  # seconds since the render started
    rays: dict  # rays traced so far, by kind name, and "total"


def render(
    scene: Scene | CompiledScene,
    threads: int | None = None,
    progress: Callable[[Progress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    on_pass: Callable[[PassResult], None] | None = None,
    device: str = "cpu",
) -> RenderResult:
    """Render a scene progressively.

    `progress` is called after each band of rows, `on_pass` after each pass with the running
    image, `cancel` before each pass: when it returns True the render stops and the result
    holds the samples finished so far (`cancelled` = True).
    """
    cs = scene if isinstance(scene, CompiledScene) else compile_scene(scene, device=device)
    r = Renderer(cs, threads, device)
    total = r.width * r.height * r.spp
    start = time.perf_counter()
    done = 0
    passes = 0
    cancelled = False

    def on_band(n_pixels: int) -> None:
        nonlocal done
        done += n_pixels * (s1 - s0)
        if progress:
            progress(Progress(done, total, passes, time.perf_counter() - start))

    for s0, s1 in pass_schedule(r.spp):
        if cancel is not None and cancel():
            cancelled = True
            break
        r.add_samples(s0, s1, on_band)
        passes += 1
        if on_pass is not None:
            on_pass(PassResult(r.image(), s1, r.spp, passes, time.perf_counter() - start, r.rays()))
    seconds = time.perf_counter() - start
    return RenderResult(
        image=r.image(), spp=r.samples_done, seconds=seconds, rays=r.rays(), cancelled=cancelled, aovs=r.aovs()
    )
