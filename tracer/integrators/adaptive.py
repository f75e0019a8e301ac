"""Adaptive supersampling (Whitted 1980): rays at the 4 corners and the centre of the pixel; if the
5 colours are within `threshold` their average is the pixel, otherwise the pixel is cut into 4
cells, each treated the same way (its corners are shared with its neighbours), down to
`max_level`. All points lie on one fine grid of (G+1)^2 points, G = 2^(max_level+1); a point's
colour is traced once and kept in a per-thread cache, and its random numbers are keyed by its
index on that grid, so pass L (subdivision stopped at level L) re-traces nothing differently.
A pixel whose every cell stopped on the threshold (none on the level limit) is finished: a deeper
pass would make the same choices, the same sums in the same order. `done` marks it, and later
passes leave its film values alone instead of tracing it again.
A pixel still being refined is not traced again from level 0 either. Pass L visits the cells of
pass L - 1 (the same colours make the same choices) and splits those that stopped at level L - 1
on the limit; every grid point it needs below level L was traced by pass L - 1, and every point of
level L is new (a level-L cell's corners are its parent's corners, centre and edge midpoints). So a
pass keeps the colours of the points it used, per pixel, in a slot of `AdaptiveKeep.next` (points
numbered level by level, see point_slot), and the next pass reads them from there (its `prev`) and
traces only the points of its own level: over all passes, each point once. The slots are the
render's to give (tracer/rendering/progressive.py, within ADAPTIVE_KEEP_BYTES); a pixel without a slot of the
pass before is traced from level 0, as a single pass is.

`make_adaptive(trace_outlined, module)` makes the sampler's kernel, `render_adaptive`, for one
integrator's `trace` (dispatch.make_kernels gives it the out-of-line copy), in that integrator's Warp
module, with `grid_trace`, the estimate at one grid point (the ray tree's too).
"""

import warp as wp

from tracer.integrators.common import SampleOut, Stack
from tracer.integrators.pixel import FilmBuffers, band_pixel, eye_ray
from tracer.integrators.record import TreeRecord
from tracer.kernels.sampling import pixel_key, rng_start
from tracer.kernels.structs import SceneData

ADAPTIVE_STACK = 32  # cells pending at once: 3 more per level of subdivision (max_level <= 8 in the scene format)
vec_cells = wp.types.vector(length=ADAPTIVE_STACK, dtype=wp.int32)
PASSES_PER_PIXEL = wp.constant(16)  # cache stamps: pixel * this + pass level + 1 (levels 0..8)


@wp.struct
class AdaptiveCache:
    color: wp.array2d(dtype=wp.vec3)  # (threads of a band, (G+1)^2) colours of traced grid points
    stamp: wp.array2d(dtype=wp.int32)  # which pixel and pass filled each entry


@wp.struct
class AdaptiveKeep:
    """The colours of the grid points pixels used, kept from one adaptive pass for the next."""

    prev: wp.array2d(dtype=wp.vec3)  # (slots, kept_points(L - 1)): the colours pass L - 1 kept
    prev_slot: wp.array2d(dtype=wp.int32)  # (H, W): a pixel's row of `prev`, -1 for none
    next: wp.array2d(dtype=wp.vec3)  # (slots, kept_points(L)): the colours this pass keeps for the next
    next_slot: wp.array2d(dtype=wp.int32)  # (H, W): a pixel's row of `next`, -1 for none


def kept_points(level: int) -> int:
    """Grid points a pixel may use with subdivision down to `level`: (2^L + 1)^2 cell corners and 4^L
    centres (samples.adaptive_count). A slot of AdaptiveKeep holds them numbered level by level."""
    return ((1 << level) + 1) ** 2 + (1 << (2 * level)) if level >= 0 else 0


@wp.func
def level_start(level: int) -> int:
    """The first slot index of `level`'s points: kept_points(level - 1)."""
    if level == 0:
        return 0
    n = 1 << (level - 1)
    return (n + 1) * (n + 1) + n * n


@wp.func
def point_slot(i: int, j: int, g: int, top: int):
    """(level, slot index) of fine-grid point (i, j) (g cells a side, levels 0..top): the level of the
    first cells that use it, and its place in a slot of AdaptiveKeep. Level 0: the pixel's corners 0-3
    and its centre 4; level L >= 1 (cells of s = g >> L grid steps): the 4^L cell centres, then the
    corners that coarser cells do not have (on the lattice of step s, one coordinate an odd multiple
    of s), numbered in row order."""
    level = int(-1)
    index = int(0)
    if (i & (g - 1)) == 0 and (j & (g - 1)) == 0:  # g = 2^(top + 1): shifts and masks, no division
        level = 0
        index = (j >> (top + 1)) * 2 + (i >> (top + 1))
    elif i == g >> 1 and j == g >> 1:
        level = 0
        index = 4
    lv = int(1)
    while level < 0 and lv <= top:
        shift = top + 1 - lv  # the cells of level lv are s = 2^shift grid steps
        mask = (1 << shift) - 1
        half = 1 << (shift - 1)
        n = 1 << lv
        if (i & mask) == 0 and (j & mask) == 0:  # a corner of level-lv cells (both odd multiples: a centre of lv - 1)
            level = lv
            index = level_start(lv) + n * n + (((j >> shift) * (n + 1) + (i >> shift) - 1) >> 1)
        elif (i & mask) == half and (j & mask) == half:  # a centre of a level-lv cell
            level = lv
            index = level_start(lv) + (j >> shift) * n + (i >> shift)
        lv += 1
    return level, index


@wp.func(inline=True)
def grid_sample(scene: SceneData, x: int, y: int, i: int, j: int, g: int):
    """Fine-grid point (i, j) of pixel (x, y) (adaptive sampler, g cells a side): its film position,
    exactly there or jittered by up to half the grid spacing when sampler.jitter is set, its random
    state and its pixel's key. Its sample index is j (g + 1) + i."""
    rng = rng_start(scene.seed, y * scene.width + x, j * (g + 1) + i)
    fx = float(i) / float(g)
    fy = float(j) / float(g)
    if scene.jitter != 0:
        fx = wp.clamp(fx + (wp.randf(rng) - 0.5) / float(g), 0.0, 1.0)
        fy = wp.clamp(fy + (wp.randf(rng) - 0.5) / float(g), 0.0, 1.0)
    return float(x) + fx, float(y) + fy, rng, pixel_key(scene.seed, y * scene.width + x)


def make_adaptive(trace_outlined, module: str):
    """(grid_trace, render_adaptive) for an integrator's `trace_outlined` (dispatch.make_kernels), the
    kernel compiled in the Warp module `module`."""

    @wp.func(inline=True)
    def grid_trace(
        scene: SceneData, x: int, y: int, i: int, j: int, g: int, st: Stack, row: int, record: int, rec: TreeRecord
    ) -> SampleOut:
        """The integrator's estimate at fine-grid point (i, j) of pixel (x, y) (see grid_sample)."""
        fx, fy, rng, key = grid_sample(scene, x, y, i, j, g)
        o, d, time, state = eye_ray(scene, fx, fy, rng, key, j * (g + 1) + i)
        return trace_outlined(scene, o, d, time, state, key, j * (g + 1) + i, st, row, record, rec)

    @wp.func(inline=True)
    def cached_point(
        scene: SceneData,
        x: int,
        y: int,
        i: int,
        j: int,
        g: int,
        level: int,
        stamp: int,
        cache: AdaptiveCache,
        keep: AdaptiveKeep,
        carried: int,
        slot: int,
        st: Stack,
        row: int,
        rec: TreeRecord,
    ):
        """(colour, rays traced now) of grid point (i, j) in the pass at `level`: kept by the pass before
        (row `carried` of keep.prev) when below `level`, else cached by this pass, else traced now. A pixel
        with a `slot` of keep.next keeps it there for the next pass."""
        lv = int(0)
        kept = int(0)
        if carried >= 0 or slot >= 0:
            lv, kept = point_slot(i, j, g, scene.max_level)
        if carried >= 0 and lv < level:
            c = keep.prev[carried, kept]
            if slot >= 0:
                keep.next[slot, kept] = c
            return c, wp.vec4i(0)
        k = j * (g + 1) + i
        if cache.stamp[row, k] == stamp:
            return cache.color[row, k], wp.vec4i(0)
        out = grid_trace(scene, x, y, i, j, g, st, row, 0, rec)
        cache.color[row, k] = out.color
        cache.stamp[row, k] = stamp
        if slot >= 0:
            keep.next[slot, kept] = out.color
        return out.color, out.counts

    @wp.kernel(module=module)
    def render_adaptive(
        scene: SceneData,
        p0: int,
        level: int,
        st: Stack,
        rec: TreeRecord,
        film: FilmBuffers,
        cache: AdaptiveCache,
        done: wp.array2d(dtype=wp.int32),
        keep: AdaptiveKeep,
    ):
        """Pixels p0.. (row-major) by adaptive subdivision down to `level`; the film holds the result. A pixel
        marked in `done` is skipped (an earlier pass finished it); one that no cell stopped at the level limit
        is marked. A pixel whose colours the pass before kept (keep.prev_slot) traces only the points of
        `level`: its film's ray counts and AOVs hold the passes before, its rays are added."""
        row = wp.tid()
        x, y, inside = band_pixel(scene, p0, row)
        if inside == 0:
            return
        if done[y, x] != 0:
            return
        g = 1 << (scene.max_level + 1)
        stamp = (p0 + row) * PASSES_PER_PIXEL + level + 1
        carried = keep.prev_slot[y, x]
        slot = keep.next_slot[y, x]
        counts = wp.vec4i(0)
        mid = g / 2
        if carried >= 0:
            counts = film.counts[y, x]  # the rays of the passes before (the walk reads their colours)
        else:  # the centre ray first: it gives the AOVs
            centre = grid_trace(scene, x, y, mid, mid, g, st, row, 0, rec)
            cache.color[row, mid * (g + 1) + mid] = centre.color
            cache.stamp[row, mid * (g + 1) + mid] = stamp
            if slot >= 0:
                keep.next[slot, 4] = centre.color  # the centre is level 0's point 4 (point_slot)
            counts = centre.counts
            film.depth[y, x] = centre.depth
            film.normal[y, x] = centre.normal
            film.albedo[y, x] = centre.albedo
        total = wp.vec3(0.0)
        total_sq = wp.vec3(0.0)
        ci = vec_cells()
        cj = vec_cells()
        cl = vec_cells()
        sp = int(1)
        limited = int(0)  # cells stopped by the level limit, not the threshold: a deeper pass would split them
        while sp > 0:
            sp -= 1
            i0 = ci[sp]
            j0 = cj[sp]
            lv = cl[sp]
            size = g >> lv
            half = size / 2
            c0, n0 = cached_point(scene, x, y, i0, j0, g, level, stamp, cache, keep, carried, slot, st, row, rec)
            c1, n1 = cached_point(scene, x, y, i0 + size, j0, g, level, stamp, cache, keep, carried, slot, st, row, rec)
            c2, n2 = cached_point(scene, x, y, i0, j0 + size, g, level, stamp, cache, keep, carried, slot, st, row, rec)
            c3, n3 = cached_point(
                scene, x, y, i0 + size, j0 + size, g, level, stamp, cache, keep, carried, slot, st, row, rec
            )
            c4, n4 = cached_point(
                scene, x, y, i0 + half, j0 + half, g, level, stamp, cache, keep, carried, slot, st, row, rec
            )
            counts = counts + n0 + n1 + n2 + n3 + n4
            lo = wp.min(wp.min(wp.min(c0, c1), wp.min(c2, c3)), c4)
            hi = wp.max(wp.max(wp.max(c0, c1), wp.max(c2, c3)), c4)
            spread = hi - lo
            flat = wp.max(spread[0], wp.max(spread[1], spread[2])) <= scene.threshold
            if lv >= level or flat:
                if not flat:
                    limited += 1
                area = 1.0 / float(1 << (2 * lv))
                total += area * (c0 + c1 + c2 + c3 + c4) / 5.0
                sq = wp.cw_mul(c0, c0) + wp.cw_mul(c1, c1) + wp.cw_mul(c2, c2) + wp.cw_mul(c3, c3) + wp.cw_mul(c4, c4)
                total_sq += area * sq / 5.0
            else:
                for q in range(4):
                    ci[sp] = i0 + (q % 2) * half
                    cj[sp] = j0 + (q / 2) * half
                    cl[sp] = lv + 1
                    sp += 1
        film.accum[y, x] = total
        film.sumsq[y, x] = total_sq
        film.counts[y, x] = counts
        if limited == 0:
            done[y, x] = 1

    return grid_trace, render_adaptive
