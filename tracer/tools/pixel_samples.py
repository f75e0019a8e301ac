"""Where one pixel's samples go: the film positions the renderer uses, for pictures and lessons.

`pixel_samples(cs, x, y)` lists, for pixel (x, y) of a compiled scene, the point of the film each
sample's eye ray passes through, as an offset (u, v) from the pixel's corner: the ray of sample k goes
through film point (x + u, y + v) (docs/scene-format.md, "Camera rays"). The offsets are computed by
the renderer's own functions (`sampling.film_offset`, then `sampling.filter_offset`; for the adaptive
sampler the fine grid of `integrators/adaptive.grid_sample`) in a one-pixel kernel, keyed by the same
(seed, pixel, sample) random numbers, so they are the image's positions exactly.

The adaptive sampler (Whitted 1980) decides from the colours which cells to split; `pixel_samples`
follows the same rule as `adaptive.render_adaptive` (a readable copy here, tested equal to it): it
traces the corners and centre of a cell, and splits the cell while their colours differ by more than
`threshold`, down to `max_level`. It reports the cells visited and which grid points were traced.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from tracer.integrators import dispatch
from tracer.kernels.compile import CompiledScene
from tracer.kernels.kinds import SAMPLER_ADAPTIVE, Integrator
from tracer.kernels.sampling import film_offset, film_uniforms, filter_offset, pixel_key, rng_start
from tracer.kernels.structs import SceneData
from tracer.rendering.film import to_srgb8
from tracer.rendering.progressive import load_kernels as load_render_kernels
from tracer.rendering.progressive import make_record, make_stack
from tracer.scene import SceneError

MODULE = "tracer_samples"
MAX_SAMPLES = 16384  # positions listed per pixel at most: spp <= 16384, adaptive max_level <= 6


@wp.kernel(module=MODULE)
def pixel_offsets(
    scene: SceneData,
    x: int,
    y: int,
    samples: wp.array(dtype=int),
    offset: wp.array(dtype=wp.vec2),
    weight: wp.array(dtype=float),
):
    """Film offset in pixel (x, y) and filter weight of each listed sample, as the render kernels
    draw them (adaptive: the sample is the index j (G+1) + i of a point of the fine grid)."""
    t = wp.tid()
    s = samples[t]
    rng = rng_start(scene.seed, y * scene.width + x, s)
    if scene.sampler == SAMPLER_ADAPTIVE:
        g = 1 << (scene.max_level + 1)
        fx = float(s % (g + 1)) / float(g)
        fy = float(s / (g + 1)) / float(g)
        if scene.jitter != 0:
            fx = wp.clamp(fx + (wp.randf(rng) - 0.5) / float(g), 0.0, 1.0)
            fy = wp.clamp(fy + (wp.randf(rng) - 0.5) / float(g), 0.0, 1.0)
        offset[t] = wp.vec2(fx, fy)
        weight[t] = 1.0
    else:
        u1, u2, rng = film_uniforms(scene.sampler, pixel_key(scene.seed, y * scene.width + x), s, rng)
        off, w = filter_offset(scene, film_offset(scene.sampler, s, scene.spp, u1, u2))
        offset[t] = off
        weight[t] = w


def load_kernels(device: str = "cpu") -> None:
    """Compile this module's kernel (or load it from Warp's cache) with the render kernels."""
    load_render_kernels(device)
    wp.load_module(MODULE, device=device)


def strata(sampler: str, spp: int) -> int | None:
    """grid and jittered: the n x n cells of the pixel, sample k in column k % n, row k // n."""
    return int(math.floor(math.sqrt(spp) + 0.5)) if sampler in ("grid", "jittered") else None


def adaptive_levels(max_level: int) -> dict[int, int]:
    """Sample index -> subdivision level of every point of the fine grid that some cell uses: a level-L
    cell (edge g >> L, g = 2^(max_level+1) grid steps) uses its four corners and its centre."""
    g = 1 << (max_level + 1)
    levels: dict[int, int] = {}
    for level in range(max_level + 1):
        size = g >> level
        for j in range(0, g + 1, size // 2):
            for i in range(0, g + 1, size // 2):
                corner = i % size == 0 and j % size == 0
                centre = i % size == size // 2 and j % size == size // 2
                if corner or centre:
                    levels.setdefault(j * (g + 1) + i, level)
    return dict(sorted(levels.items()))


def adaptive_count(max_level: int) -> int:
    """Points of the fine grid the adaptive sampler may trace: (2^L + 1)^2 corners and 4^L centres."""
    return ((1 << max_level) + 1) ** 2 + (1 << (2 * max_level))


def _offsets(cs: CompiledScene, x: int, y: int, samples: list[int], device: str) -> tuple[np.ndarray, np.ndarray]:
    idx = wp.array(np.asarray(samples, dtype=np.int32), dtype=int, device=device)
    off = wp.zeros(len(samples), dtype=wp.vec2, device=device)
    w = wp.zeros(len(samples), dtype=float, device=device)
    wp.launch(pixel_offsets, dim=len(samples), inputs=[cs.data, x, y, idx, off, w], device=device)
    return off.numpy(), w.numpy()


def _subdivide(cs: CompiledScene, x: int, y: int, device: str) -> tuple[dict[int, np.ndarray], list[dict]]:
    """The adaptive sampler's pass at max_level for one pixel: the colours of the grid points it traced
    (sample index -> linear RGB, float32) and the cells it visited. Mirrors `render_adaptive`."""
    d = cs.data
    g = 1 << (d.max_level + 1)
    trace_one = dispatch.KERNELS[Integrator(d.integrator)][2]
    st, rec = make_stack(1, d.max_depth, device), make_record(0, device)
    out = wp.zeros(2, dtype=wp.vec3, device=device)
    colours: dict[int, np.ndarray] = {}

    def colour(i: int, j: int) -> np.ndarray:
        k = j * (g + 1) + i
        if k not in colours:
            wp.launch(trace_one, dim=1, inputs=[d, x, y, k, st, rec, out], device=device)
            colours[k] = out.numpy()[0].copy()
        return colours[k]

    threshold = np.float32(d.threshold)
    colour(g // 2, g // 2)  # the kernel traces the centre first (it gives the AOVs)
    cells, stack = [], [(0, 0, 0)]
    while stack:
        i0, j0, level = stack.pop()
        size = g >> level
        five = np.stack(
            [colour(i, j) for i, j in ((i0, j0), (i0 + size, j0), (i0, j0 + size), (i0 + size, j0 + size))]
            + [colour(i0 + size // 2, j0 + size // 2)]
        )
        spread = float((five.max(axis=0) - five.min(axis=0)).max())
        split = not (level >= d.max_level or spread <= threshold)
        mean = five.mean(axis=0)
        cells.append({"corner": [i0 / g, j0 / g], "size": size / g, "level": level, "split": split, "mean": mean})
        if split:
            half = size // 2
            stack.extend((i0 + (q % 2) * half, j0 + (q // 2) * half, level + 1) for q in (3, 2, 1, 0))
    return colours, cells


def _hex(rgb8) -> str:
    return "#" + "".join(f"{int(c):02x}" for c in rgb8)


def pixel_samples(cs: CompiledScene, x: int, y: int, max_samples: int = MAX_SAMPLES, device: str = "cpu") -> dict:
    """The samples of pixel (x, y): their film offsets and filter weights, in sample order; for the
    adaptive sampler every point of its grid levels, whether this pixel traced it and the cells it
    visited (colours as the PNG shows them, '#rrggbb'). Raises SceneError (at paths x, y, sampler.spp,
    sampler.max_level) for a pixel off the film, or more than `max_samples` samples to list."""
    d, sm = cs.data, cs.scene.sampler
    adaptive = sm.type == "adaptive"
    errs = []
    if not 0 <= x < d.width:
        errs.append({"path": "x", "message": f"must be a column in 0..{d.width - 1}"})
    if not 0 <= y < d.height:
        errs.append({"path": "y", "message": f"must be a row in 0..{d.height - 1}"})
    count = adaptive_count(d.max_level) if adaptive else d.spp
    if count > max_samples:
        what = f"max_level {d.max_level} has {count} grid points" if adaptive else f"{count} samples per pixel"
        errs.append(
            {
                "path": "sampler.max_level" if adaptive else "sampler.spp",
                "message": f"{what}; at most {max_samples} sample positions are listed per pixel",
            }
        )
    if errs:
        raise SceneError(errs)
    levels = adaptive_levels(d.max_level) if adaptive else {}
    samples = list(levels) if adaptive else list(range(d.spp))
    off, w = _offsets(cs, x, y, samples, device)
    exposure = cs.scene.film.exposure
    result = {
        "pixel": [x, y],
        "sampler": sm.type,
        "filter": {"type": cs.scene.film.filter.type, "radius": cs.scene.film.filter.radius},
        "strata": strata(sm.type, d.spp),
        "max_level": d.max_level if adaptive else None,
        "samples": [],
        "cells": None,
    }
    colours: dict[int, np.ndarray] = {}
    if adaptive:
        colours, cells = _subdivide(cs, x, y, device)
        means = to_srgb8(np.array([c.pop("mean") for c in cells], dtype=np.float32), exposure)
        result["cells"] = [{**c, "srgb": _hex(m)} for c, m in zip(cells, means, strict=True)]
    shown = {}
    if colours:
        shown = dict(zip(colours, map(_hex, to_srgb8(np.array(list(colours.values())), exposure)), strict=True))
    for n, k in enumerate(samples):
        item = {"sample": k, "position": [float(off[n][0]), float(off[n][1])], "weight": float(w[n])}
        if adaptive:
            item.update(level=levels[k], traced=k in colours, srgb=shown.get(k))
        result["samples"].append(item)
    return result
