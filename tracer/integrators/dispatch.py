"""The render kernels: thread -> pixel -> sample -> RNG -> camera ray -> the scene's integrator.

`render_pixels` adds samples s0..s1-1 of every pixel of a band to the film's running sums
(one thread per pixel, samples in order, so any split into passes gives the same sums);
`render_adaptive` runs the adaptive sampler (adaptive.py); `trace_one` traces one pixel sample with its ray
tree recorded. `make_kernels(trace, module)` builds the three for one integrator's `trace` (Warp
kernel closures) in a Warp module of their own, so each compiled unit holds one integrator's
code: with every integrator in one unit, the Whitted kernels ran 1.5x slower (the C++ compiler
inlines the shared helpers less when more code calls them). `KERNELS` has them for every
integrator of the table in tracer/scene/integrators.py, each made when first asked for.
"""

import importlib
import threading
from collections.abc import Mapping

import warp as wp

from tracer.integrators.adaptive import make_adaptive
from tracer.integrators.common import SampleOut, Stack
from tracer.integrators.pixel import FilmBuffers, band_pixel, eye_ray, pixel_sample
from tracer.integrators.record import TreeRecord
from tracer.kernels.kinds import SAMPLER_ADAPTIVE, Integrator
from tracer.kernels.structs import SceneData
from tracer.scene.integrators import INTEGRATORS

__all__ = ["KERNELS", "KERNEL_MODULES", "FilmBuffers", "kernel_modules", "make_kernels"]


def make_kernels(trace, module: str):
    """(render_pixels, render_adaptive, trace_one) for an integrator's `trace` (the signature in
    tracer/scene/integrators.py), compiled together as the Warp module `module`."""

    @wp.func(inline=False)
    def trace_outlined(
        scene: SceneData,
        o: wp.vec3,
        d: wp.vec3,
        time: float,
        rng: wp.uint32,
        key: wp.uint32,
        sample: int,
        st: Stack,
        row: int,
        record: int,
        rec: TreeRecord,
    ) -> SampleOut:
        """`trace` compiled once, out of line, for the adaptive sampler and the ray tree. render_pixels
        inlines it (with record = 0 the ray tree's code folds away: 1.4x faster), but an inlined copy at
        each call site of the other kernels would take minutes to compile (BENCHMARKS.md)."""
        return trace(scene, o, d, time, rng, key, sample, st, row, record, rec)

    grid_trace, render_adaptive = make_adaptive(trace_outlined, module)  # the adaptive sampler (adaptive.py)

    @wp.kernel(module=module)
    def render_pixels(scene: SceneData, p0: int, s0: int, s1: int, st: Stack, rec: TreeRecord, film: FilmBuffers):
        """Add samples s0..s1-1 of pixels p0.. (row-major) to the film's sums (one thread per pixel)."""
        row = wp.tid()
        x, y, inside = band_pixel(scene, p0, row)
        if inside == 0:
            return
        acc = film.accum[y, x]
        sq = film.sumsq[y, x]
        cnt = film.counts[y, x]
        dep = film.depth[y, x]
        nrm = film.normal[y, x]
        alb = film.albedo[y, x]
        for s in range(s0, s1):
            fx, fy, weight, rng, key = pixel_sample(scene, x, y, s)
            o, d, time, state = eye_ray(scene, fx, fy, rng, key, s)
            out = trace(scene, o, d, time, state, key, s, st, row, 0, rec)
            c = out.color * weight  # the sample times its filter weight
            acc = acc + c
            sq = sq + wp.cw_mul(c, c)
            cnt = cnt + out.counts
            dep = dep + out.depth
            nrm = nrm + out.normal
            alb = alb + out.albedo
        film.accum[y, x] = acc
        film.sumsq[y, x] = sq
        film.counts[y, x] = cnt
        film.depth[y, x] = dep
        film.normal[y, x] = nrm
        film.albedo[y, x] = alb

    @wp.kernel(module=module)
    def trace_one(scene: SceneData, x: int, y: int, s: int, st: Stack, rec: TreeRecord, out: wp.array(dtype=wp.vec3)):
        """One pixel sample with its ray tree recorded: out[0] its radiance times its filter weight, out[1][0]
        the weight (adaptive: s is the index of a fine-grid point, weight 1)."""
        if scene.sampler == SAMPLER_ADAPTIVE:
            g = 1 << (scene.max_level + 1)
            r = grid_trace(scene, x, y, s % (g + 1), s / (g + 1), g, st, 0, 1, rec)
            out[0] = r.color
            out[1] = wp.vec3(1.0, 0.0, 0.0)
        else:
            fx, fy, weight, rng, key = pixel_sample(scene, x, y, s)
            o, d, time, state = eye_ray(scene, fx, fy, rng, key, s)
            r = trace_outlined(scene, o, d, time, state, key, s, st, 0, 1, rec)
            out[0] = r.color * weight
            out[1] = wp.vec3(weight, 0.0, 0.0)

    return render_pixels, render_adaptive, trace_one


def _kernels_of(module: str):
    """The kernels of integrator module `module`, made once however many integrators share them."""
    with _BUILDING:
        if module not in _BUILT:
            trace = importlib.import_module(f"tracer.integrators.{module}").trace
            _BUILT[module] = make_kernels(trace, KERNEL_MODULES[module])
    return _BUILT[module]


class _Kernels(Mapping):
    """KERNELS[integrator]: its (render_pixels, render_adaptive, trace_one), made on first use. A command
    imports an integrator's module and defines its kernels only when its scene needs them: the path
    integrator's cost nothing to a Whitted render's start-up (BENCHMARKS.md, #17)."""

    def __getitem__(self, integrator) -> tuple:
        return _kernels_of(INTEGRATORS[Integrator(integrator)].kernels)

    def __iter__(self):
        return iter(Integrator)

    def __len__(self) -> int:
        return len(Integrator)


def kernel_modules(integrators=None) -> list[str]:
    """The Warp modules of `integrators`' kernels (default: every integrator's), each once, their kernels
    made: what `wp.load_module` loads."""
    names: list[str] = []
    for i in Integrator if integrators is None else integrators:
        KERNELS[i]
        name = KERNEL_MODULES[INTEGRATORS[Integrator(i)].kernels]
        if name not in names:
            names.append(name)
    return names


_BUILT: dict = {}
_BUILDING = threading.Lock()
KERNEL_MODULES = {i.kernels: f"tracer_kernels_{i.kernels}" for i in INTEGRATORS}  # Warp module of each
KERNELS = _Kernels()
