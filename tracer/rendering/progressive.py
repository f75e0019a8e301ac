"""Rendering: progressive passes over bands of rows, launched from a thread pool.

A Warp CPU launch runs on one thread and releases the GIL, so bands of rows are launched
from one Python thread per core. Each pixel's samples are added in sample order by a single
thread into a float accumulation buffer, so the image is bit-identical for any thread count,
band size or split of the samples into passes (the RNG is keyed by seed, pixel and sample).

On a CUDA device the band is the whole image: one launch per pass, no thread pool (bands of
4096 pixels would starve a GPU). `Renderer(..., band=None)` asks for the same on the CPU, and
gives the same image there, bit for bit. The one bound: a launch's scratch memory (ray stacks,
the adaptive sampler's cache) stays within WHOLE_IMAGE_SCRATCH_BYTES; a bigger image is launched
in the fewest bands that fit, one after the other.

A launch cannot be stopped, and a cancel is seen between launches (`on_band` follows each), so no
launch is long: a band is cut into launches of fewer pixels, or of fewer of a pass's samples, of at
most LAUNCH_RAYS rays if every sample traced the most rays it can (estimate.most_rays_per_sample: the
bound on its ray tree) and, once a launch has been timed, of about LAUNCH_SECONDS. Any such cut
gives the same sums, so the image does not depend on it.
"""

from __future__ import annotations

import io
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import warp as wp

from tracer.errors import Cancelled
from tracer.integrators import adaptive, dispatch, record
from tracer.integrators.common import Stack
from tracer.kernels.compile import CompiledScene, compile_scene
from tracer.kernels.kinds import Integrator, RayKind, SamplerKind
from tracer.kernels.parallel import default_threads, is_cuda, thread_pool
from tracer.kernels.structs import empty
from tracer.rendering import estimate
from tracer.scene import Scene
from tracer.scene.integrators import INTEGRATORS

if TYPE_CHECKING:
    from tracer import radiosity
    from tracer.radiosity.solver import Solution

BAND_PIXELS = 4096  # pixels per launch: small enough to balance two threads, large enough to amortise
ADAPTIVE_CACHE_BYTES = 32 << 20  # per thread: the adaptive sampler's cache of traced grid points
ADAPTIVE_KEEP_BYTES = 256 << 20  # the colours an adaptive pass keeps for the next (see Renderer.adaptive_pass)
KEEP_BYTES_PER_POINT = 12  # a kept grid point: its colour (vec3)
WHOLE_IMAGE_SCRATCH_BYTES = 2 << 30  # whole-image launches: the most their stacks and cache may take
STACK_BYTES_PER_LEVEL = 6 * 12  # a pixel's ray stack: o, d, k, w, tau (vec3) and i (vec3i) per depth
CACHE_BYTES_PER_POINT = 12 + 4  # a pixel's adaptive cache: a colour (vec3) and a stamp (int32) per grid point
AUTO = "auto"  # Renderer(band=AUTO): the whole image on a CUDA device, BAND_PIXELS on the CPU
LAUNCH_RAYS = 8_000_000  # the most rays a CPU launch may trace (about a second on one thread; a cancel waits for it)
CUDA_LAUNCH_RAYS = 1 << 29  # the same on a CUDA device (a fraction of a second there)
LAUNCH_SECONDS = 0.25  # a launch's length once the pace of the ones before is known


def band_size(device: str, pixels: int, max_depth: int, grid_points: int, band: int | str | None = AUTO) -> int:
    """Pixels per launch. `band` AUTO: the whole image on a CUDA device, BAND_PIXELS on the CPU; None: the
    whole image; a number: that many. The whole image is bounded by WHOLE_IMAGE_SCRATCH_BYTES of scratch
    (ray stacks, and the adaptive sampler's cache of `grid_points` per pixel); bands on the CPU by
    ADAPTIVE_CACHE_BYTES of cache per thread."""
    if band == AUTO:
        band = None if is_cuda(device) else BAND_PIXELS
    cache = grid_points * CACHE_BYTES_PER_POINT
    if band is None:
        per_pixel = (max_depth + 1) * STACK_BYTES_PER_LEVEL + cache
        fit = max(1, WHOLE_IMAGE_SCRATCH_BYTES // per_pixel)
        bands = -(-pixels // fit)  # the fewest bands that fit, as equal as can be
        return -(-pixels // bands)
    if grid_points:
        band = min(band, ADAPTIVE_CACHE_BYTES // cache)
    return int(max(1, min(band, pixels)))


def make_stack(rows: int, depth: int, device: str = "cpu") -> Stack:
    st = Stack()
    shape = (rows, depth + 1)
    st.o = empty(shape, dtype=wp.vec3, device=device)
    st.d = empty(shape, dtype=wp.vec3, device=device)
    st.k = empty(shape, dtype=wp.vec3, device=device)
    st.w = empty(shape, dtype=wp.vec3, device=device)
    st.tau = empty(shape, dtype=wp.vec3, device=device)
    st.i = empty(shape, dtype=wp.vec3i, device=device)
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


def load_kernels(device: str = "cpu", integrators=None) -> None:
    """Compile the render kernels of `integrators` (Integrator values; default: every integrator's), or load
    them from Warp's disk cache (call before threads start). A long-lived process (a service worker) loads
    them all once; a command loads only its scene's: each module loaded costs the hash of its source."""
    for module in dispatch.kernel_modules(integrators):
        wp.load_module(module, device=device)


@dataclass
class Progress:
    """What a progress callback sees after each launch of each pass (a band of pixels, or a piece of one), and
    after each shot of a radiosity solve, which comes first: `phase` "radiosity", with `solve` telling how far
    it is."""

    samples_done: int  # pixel samples finished so far
    samples_total: int
    passes_done: int
    elapsed: float  # seconds
    phase: str = "render"  # "radiosity" while the radiosity solution is being solved, then "render"
    solve: dict | None = None  # the solve so far: fraction (0..1), shots, rays, seconds, unshot (share)


@dataclass
class Kept:
    """The colours an adaptive pass kept for the next (Renderer.adaptive_pass): a slot of
    adaptive.kept_points(level) colours for each pixel that got one."""

    level: int  # the pass's subdivision level
    colours: wp.array  # 2-D (slots, kept_points(level)) vec3, numbered as adaptive.point_slot numbers them
    slots: np.ndarray  # (H, W) int32: each pixel's row of `colours`, -1 for none
    slots_wp: wp.array  # the same on the device (2-D)

    @property
    def nbytes(self) -> int:
        return self.colours.shape[0] * self.colours.shape[1] * KEEP_BYTES_PER_POINT


@dataclass
class RenderResult:
    image: np.ndarray  # (H, W, 3) float32 linear radiance, the mean of the samples
    spp: int  # samples per pixel in `image`
    seconds: float
    rays: dict = field(default_factory=dict)  # rays by kind name, and "total"
    cancelled: bool = False
    aovs: dict = field(default_factory=dict)  # name -> (H, W) or (H, W, 3) float32, see Renderer.aovs
    solve: dict | None = None  # the radiosity solve's cost (shots, rays, seconds, unshot), if one ran

    def stats_line(self) -> str:
        """Seconds, rays by kind and Mrays/s; with a radiosity solve, its share of the time and rays
        (the solve's rays are the `radiosity` kind)."""
        total = self.rays.get("total", 0)
        kinds = " ".join(f"{k}={v}" for k, v in self.rays.items() if k != "total")
        mrays = total / self.seconds / 1e6 if self.seconds > 0 else 0.0
        line = f"{self.seconds:.3f} s, {total} rays ({kinds}), {mrays:.2f} Mrays/s"
        if self.solve:
            s = self.solve
            line += f"; radiosity solve: {s['seconds']:.2f} s, {s['shots']} shots, {s['patches']} patch sides"
        return line


def adaptive_schedule(cs: CompiledScene) -> list[tuple[int, int]]:
    """Adaptive passes: level 0 (5 rays a pixel), then one more level of subdivision each pass.
    Each pair is (level, level + 1) so progress counts one unit per pixel per pass."""
    return [(level, level + 1) for level in range(cs.data.max_level + 1)]


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
    """A compiled scene with its film buffers.

    Uniform samplers: `add_samples(s0, s1)` adds samples to the running sums. Adaptive sampler:
    `adaptive_pass(level)` refines the film down to `level`: the pixels earlier passes left unfinished.
    Work is cut into bands of consecutive pixels launched from one thread per core; on a CUDA device
    (or with `band=None`) the band is the whole image, launched from this thread (see `band_size`).
    `keep_bytes`: the most memory an adaptive pass may keep colours in for the next (see adaptive_pass).
    """

    def __init__(
        self,
        compiled: CompiledScene,
        threads: int | None = None,
        device: str = "cpu",
        band: int | str | None = AUTO,
        keep_bytes: int = ADAPTIVE_KEEP_BYTES,
    ):
        on = str(compiled.data.shapes.device)  # a wp.Device prints as its alias: cpu, cuda:0
        if on != str(wp.get_device(device)):
            raise ValueError(f"the scene was compiled for {on}, not {device}: compile_scene(scene, device={device!r})")
        self.cs = compiled
        self.device = device
        self.cuda = is_cuda(device)
        data = compiled.data
        load_kernels(device, [data.integrator])
        self.width, self.height, self.spp = data.width, data.height, data.spp
        self.adaptive = data.sampler == SamplerKind.ADAPTIVE
        self.render_pixels, self.render_adaptive, _ = dispatch.KERNELS[Integrator(data.integrator)]
        points = ((1 << (data.max_level + 1)) + 1) ** 2 if self.adaptive else 0
        # launches on a CUDA device go one after the other into its stream: never from a pool
        self.threads = 1 if self.cuda or band is None else threads or default_threads()
        self.band = band_size(device, self.width * self.height, data.max_depth, points, band)
        if self.adaptive:
            self.caches = []
            for _ in range(self.threads):
                c = adaptive.AdaptiveCache()
                c.color = empty((self.band, points), dtype=wp.vec3, device=device)
                c.stamp = wp.zeros((self.band, points), dtype=wp.int32, device=device)
                self.caches.append(c)
            self.done = wp.zeros((self.height, self.width), dtype=wp.int32, device=device)  # pixels finished
            self.keep_bytes = keep_bytes
            self.kept: Kept | None = None  # the colours the last pass kept for the next
            self.no_slots = wp.full((self.height, self.width), -1, dtype=wp.int32, device=device)
            self.no_colours = empty((1, 1), dtype=wp.vec3, device=device)
        self.film = make_film(self.height, self.width, device)
        self.stacks = [make_stack(self.band, data.max_depth, device) for _ in range(self.threads)]
        self.dummy = make_record(0, device)
        self.samples_done = 0  # per pixel (adaptive: 1 once a pass has run)
        self.passes_rays = np.zeros(len(RayKind), dtype=np.int64)  # adaptive: rays of the passes before the last
        self.sample_rays = estimate.most_rays_per_sample(compiled.scene, data.max_tree_rays)  # at most, per sample
        self.launch_rays = CUDA_LAUNCH_RAYS if self.cuda else LAUNCH_RAYS
        self.pace = 0.0  # seconds per unit of work of the last launch (0: none timed yet)

    def _units(self, unit_rays: int) -> int:
        """Units of work (pixel samples, or pixels of an adaptive pass) the next launch may take: at most
        launch_rays rays if each unit traced `unit_rays`, the most it can, and about LAUNCH_SECONDS at the
        pace of the last launch."""
        units = self.launch_rays // max(1, unit_rays)
        if self.pace > 0:
            units = min(units, int(LAUNCH_SECONDS / self.pace))
        return max(1, units)

    def _run(
        self,
        launch: Callable[[int, int, int, int, int], None],
        on_band: Callable[[int], None] | None,
        samples: tuple[int, int] = (0, 1),
        unit_rays: int = 1,
    ) -> None:
        """launch(worker, first pixel, pixel count, first sample, end sample) over every band, one worker thread
        per core (one thread, this one, on a CUDA device or when the band is the whole image), each band in
        launches of at most `_units(unit_rays)` pixel samples (an adaptive pass: samples (0, 1), a unit a
        pixel), a band's launches one after the other on its thread, so each pixel's samples are added in
        order. `on_band(units)` follows each launch; when it raises (a cancel), every thread stops before its
        next launch, and the exception is raised here once they all have."""
        total = self.width * self.height
        bands = [(p0, min(self.band, total - p0)) for p0 in range(0, total, self.band)]
        queue = iter(bands)
        lock = threading.Lock()
        s0, s1 = samples
        stopped = threading.Event()

        def timed(k: int, p: int, m: int, a: int, b: int) -> None:
            start = time.perf_counter()
            launch(k, p, m, a, b)
            if self.cuda:  # a CUDA launch returns at once: the pace and the progress count finished work
                wp.synchronize_device(self.device)
            with lock:
                self.pace = (time.perf_counter() - start) / (m * (b - a))
                if on_band and not stopped.is_set():
                    try:
                        on_band(m * (b - a))
                    except BaseException:
                        stopped.set()
                        raise

        def worker(k: int) -> None:
            while True:
                with lock:
                    item = next(queue, None)
                if item is None:
                    return
                p, end = item[0], item[0] + item[1]
                while p < end:  # pixels p .. p + m - 1, through the samples in launches of n
                    m = min(end - p, max(1, self._units(unit_rays) // (s1 - s0)))
                    s = s0
                    while s < s1:
                        if stopped.is_set():
                            return
                        n = min(s1 - s, max(1, self._units(unit_rays) // m))
                        timed(k, p, m, s, s + n)
                        s += n
                    p += m

        if self.threads == 1:
            worker(0)
        else:
            pool = thread_pool(self.threads)
            futures = [pool.submit(worker, k) for k in range(self.threads)]
            errors = [e for e in (f.exception() for f in futures) if e is not None]  # waits for every thread
            if errors:
                raise errors[0]
        wp.synchronize_device(self.device)

    def add_samples(self, s0: int, s1: int, on_band: Callable[[int], None] | None = None) -> None:
        """Trace samples s0..s1-1 of every pixel."""

        def launch(k: int, p0: int, n: int, a: int, b: int) -> None:
            wp.launch(
                self.render_pixels,
                dim=n,
                device=self.device,
                inputs=[self.cs.data, p0, a, b, self.stacks[k], self.dummy, self.film],
            )

        self._run(launch, on_band, (s0, s1), self.sample_rays)
        self.samples_done = s1

    def adaptive_pass(self, level: int, on_band: Callable[[int], None] | None = None) -> None:
        """Adaptive supersampling of every pixel with subdivision down to `level` (<= max_level). A pixel that
        an earlier pass finished (no cell stopped at its level limit) keeps its film values: a pass traces only
        the pixels still being refined, and gives the image a single pass at `level` gives, bit for bit.

        A pass below max_level keeps, for each pixel it traces, the colours of the grid points it used, and
        the next pass (at level + 1) traces only its own level's points for those pixels: over all passes,
        each point once. The colours kept take at most `keep_bytes`: the pixels traced get slots in row order
        while they fit (a pixel needs kept_points(level) colours of 12 bytes), and a pixel without one is
        traced from level 0 by the next pass (its rays counted again). While a pass runs it holds the
        colours of the pass before as well: 2 * keep_bytes at most. Snapshots do not hold them: a restored
        render traces the pixels still unfinished from level 0 in its first pass."""
        todo = self.done.numpy() == 0
        old = self.kept if self.kept is not None and self.kept.level == level - 1 else None
        carried = todo & (old.slots >= 0) if old is not None else np.zeros_like(todo)
        if self.samples_done:  # the pixels traced again from level 0: their counts of the pass before are overwritten
            again = todo & ~carried
            self.passes_rays += self.film.counts.numpy()[again].astype(np.int64).sum(axis=0)
        new = self._keep(level, todo) if level < self.cs.data.max_level else None  # the last pass keeps nothing
        keep = adaptive.AdaptiveKeep()
        keep.prev, keep.prev_slot = (old.colours, old.slots_wp) if old else (self.no_colours, self.no_slots)
        keep.next, keep.next_slot = (new.colours, new.slots_wp) if new else (self.no_colours, self.no_slots)

        def launch(k: int, p0: int, n: int, a: int, b: int) -> None:
            inputs = [self.cs.data, p0, level, self.stacks[k], self.dummy, self.film, self.caches[k], self.done, keep]
            wp.launch(self.render_adaptive, dim=n, device=self.device, inputs=inputs)

        self.kept = None  # the colours of the pass before are freed once this pass has read them
        self.pace = 0.0  # a deeper level costs more a pixel: timed afresh
        self._run(launch, on_band, unit_rays=self.sample_rays * adaptive.kept_points(level))
        self.kept = new
        self.samples_done = 1

    def _keep(self, level: int, todo: np.ndarray) -> Kept | None:
        """Slots for the colours the pass at `level` keeps: the pixels it traces (`todo`), in row order, as
        many as keep_bytes holds. None when not one fits."""
        points = adaptive.kept_points(level)
        n = min(int(todo.sum()), self.keep_bytes // (points * KEEP_BYTES_PER_POINT))
        if n == 0:
            return None
        slots = np.full(todo.shape, -1, dtype=np.int32)
        slots.flat[np.flatnonzero(todo)[:n]] = np.arange(n, dtype=np.int32)
        colours = empty((n, points), dtype=wp.vec3, device=self.device)
        return Kept(level, colours, slots, wp.array(slots, dtype=wp.int32, device=self.device))

    FIELDS = ("accum", "sumsq", "counts", "depth", "normal", "albedo")

    def snapshot(self) -> dict:
        """The film's running sums as numpy arrays: enough to resume the render later, elsewhere."""
        snap = {name: getattr(self.film, name).numpy().copy() for name in self.FIELDS}
        snap["samples_done"] = self.samples_done
        snap["passes_rays"] = self.passes_rays.copy()
        if self.adaptive:
            snap["done"] = self.done.numpy().copy()
        return snap

    def restore(self, snap: dict) -> None:
        """Continue from a snapshot of a render of the same scene: add_samples(snap samples, spp) then
        gives exactly the image of one uninterrupted render."""
        for name in self.FIELDS:
            target = getattr(self.film, name)
            if tuple(snap[name].shape[:2]) != tuple(target.shape):
                raise ValueError(
                    f"snapshot of a {snap[name].shape[1]}x{snap[name].shape[0]} film, not {self.width}x{self.height}"
                )
            target.assign(wp.array(snap[name], dtype=target.dtype, device=self.device))
        self.samples_done = int(snap["samples_done"])
        self.passes_rays = np.asarray(snap["passes_rays"], dtype=np.int64).copy()
        if self.adaptive:
            self.kept = None  # not in a snapshot: the next pass traces the unfinished pixels from level 0
        if self.adaptive and "done" in snap:  # a snapshot from before #17 has none: every pixel is traced again
            self.done.assign(wp.array(np.asarray(snap["done"], dtype=np.int32), dtype=wp.int32, device=self.device))

    def image(self) -> np.ndarray:
        """The mean of the samples so far, (H, W, 3) float32."""
        acc = self.film.accum.numpy()
        return (acc / max(self.samples_done, 1)).astype(np.float32)

    def aovs(self) -> dict[str, np.ndarray]:
        """Arbitrary output variables, averaged over the samples so far (float32):
        depth (H, W): distance to the eye ray's hit, 0 where it left the scene; normal (H, W, 3): the
        shading normal there; albedo (H, W, 3): kd there; rays (H, W): rays traced for the pixel, all
        kinds (adaptive: the rays of the grid points its last pass used, whichever pass traced them);
        variance (H, W, 3): the samples' variance (unbiased, per channel; adaptive: the area-weighted
        spread of the colours it averaged)."""
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
        """Rays traced so far by kind (every pass), and "total"."""
        c = self.film.counts.numpy().reshape(-1, len(RayKind)).astype(np.int64).sum(axis=0) + self.passes_rays
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
    snapshot: Callable[[], dict] | None = None  # the film now, to resume from (see `render`'s `resume`)


def snapshot_bytes(snap: dict) -> bytes:
    """A film snapshot (`PassResult.snapshot()`) as the bytes of an .npz file, to keep or send."""
    buf = io.BytesIO()
    arrays: dict[str, Any] = {k: np.asarray(v) for k, v in snap.items()}  # Any: no key is taken for savez's options
    np.savez(buf, **arrays)
    return buf.getvalue()


def snapshot_from(data: bytes) -> dict:
    """The snapshot that `snapshot_bytes` wrote."""
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        snap = {k: z[k] for k in z.files}
    for key in ("samples_done", "passes"):
        snap[key] = int(snap[key])
    return snap


def render(
    scene: Scene | CompiledScene,
    threads: int | None = None,
    progress: Callable[[Progress], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    on_pass: Callable[[PassResult], None] | None = None,
    device: str = "cpu",
    radiosity_cache: radiosity.SolutionCache | None = None,
    resume: dict | None = None,
    band: int | str | None = AUTO,
) -> RenderResult:
    """Render a scene progressively; with the radiosity integrator, solve its radiosity first (or read
    it from `radiosity_cache`).

    `progress` is called after each shot of the solve (phase "radiosity") and after each launch (a band
    of pixels, or a piece of one: see the module's docstring), `on_pass` after each pass with the running
    image, `cancel` before each shot and each pass: when it returns True the render stops and the result
    holds the samples finished so far
    (`cancelled` = True; none if the solve was not finished). `resume`: a snapshot taken after a pass
    of this scene's render (`PassResult.snapshot()`): the render goes on from there, and ends with
    exactly the image of an uninterrupted one. `device`: Warp's device ("cpu", "cuda:0"; a compiled
    scene must have been compiled for it); `band`: see `Renderer`.
    """
    start = time.perf_counter()
    cs = scene if isinstance(scene, CompiledScene) else compile_scene(scene, device=device)
    adaptive = cs.data.sampler == SamplerKind.ADAPTIVE
    pixels = cs.data.width * cs.data.height
    total = pixels * (cs.data.max_level + 1 if adaptive else cs.data.spp)
    try:
        solve = solve_radiosity(cs, threads, progress, cancel, device, start, total, radiosity_cache)
    except Cancelled:
        shape = (cs.data.height, cs.data.width, 3)
        return RenderResult(np.zeros(shape, np.float32), 0, time.perf_counter() - start, cancelled=True)
    solve_rays = solve["rays"] if solve else 0
    r = Renderer(cs, threads, device, band)
    passes = 0
    if resume is not None:
        r.restore(resume)
        passes = int(resume["passes"])
    done = pixels * (passes if adaptive else r.samples_done)
    cancelled = False

    def snapshot() -> dict:
        return {**r.snapshot(), "passes": passes}

    def all_rays() -> dict:
        rays = r.rays()
        if solve:
            rays = {**{k: v for k, v in rays.items() if k != "total"}, "radiosity": solve_rays}
            rays["total"] = sum(rays.values())
        return rays

    def on_band(units: int) -> None:  # pixel samples (adaptive: pixels of this pass's level)
        nonlocal done
        done += units
        if progress:
            progress(Progress(done, total, passes, time.perf_counter() - start))

    schedule = (adaptive_schedule(cs) if r.adaptive else pass_schedule(r.spp))[passes:]
    for s0, s1 in schedule:
        if cancel is not None and cancel():
            cancelled = True
            break
        if r.adaptive:
            r.adaptive_pass(s0, on_band)  # s0 = the subdivision level of this pass
        else:
            r.add_samples(s0, s1, on_band)
        passes += 1
        if on_pass is not None:
            elapsed = time.perf_counter() - start
            on_pass(PassResult(r.image(), r.samples_done, r.spp, passes, elapsed, all_rays(), snapshot))
    seconds = time.perf_counter() - start
    return RenderResult(
        image=r.image(),
        spp=r.samples_done,
        seconds=seconds,
        rays=all_rays(),
        cancelled=cancelled,
        aovs=r.aovs(),
        solve=solve,
    )


def solve_radiosity(
    cs: CompiledScene, threads, progress, cancel, device: str, start: float, total: int, cache=None
) -> dict | None:
    """The radiosity phase of a render: solve and attach the scene's radiosity solution when its
    integrator needs one that is not there yet, reporting each shot to `progress` (phase "radiosity")
    and asking `cancel` before each (True raises Cancelled). Returns the solve's stats. The solver is
    imported here: other scenes' renders need not load it."""
    if INTEGRATORS[cs.data.integrator].prepass != "radiosity":
        return None
    from tracer import radiosity

    if cs.radiosity is None:

        def on_step(sol, step: int) -> None:
            if progress:
                info = {**sol.stats(), "fraction": sol.fraction()}
                progress(Progress(0, total, 0, time.perf_counter() - start, phase="radiosity", solve=info))

        radiosity.attach(cs, device=device, threads=threads, on_step=on_step, cancel=cancel, cache=cache)
    # attach has set the Solution (CompiledScene cannot name the type: the kernels come before radiosity)
    return cast("Solution", cs.radiosity).stats()
