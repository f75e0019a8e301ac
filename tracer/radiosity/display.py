"""A radiosity solution made ready for the image: the smooth display's values at the patches' corners,
and `attach`, which solves (or reads from a cache) a scene's solution and hands it to the kernels.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from tracer.kernels.compile import CompiledScene
from tracer.kernels.kinds import RadDisplay
from tracer.kernels.structs import PatchIndex, RadiosityData
from tracer.radiosity.cache import SolutionCache
from tracer.radiosity.patches import Patches, patch_index
from tracer.radiosity.solver import Solution, solve


def corner_values(p: Patches, values: np.ndarray) -> np.ndarray:
    """Per patch side, the values at its triangle corners (2 triangles for a parallelogram), each the
    mean of the values of the same object's patches on the same side that share that corner (smooth
    shading of a piecewise-constant solution). Flat pieces share corners only with pieces facing the
    same way (no smoothing over a box's edges); a sphere's facets all share theirs.
    Returns (sides, 6, 3): corners of up to 2 triangles, in the order `patch_index` emits them."""
    n2 = len(p)
    quads = ~p.triangle
    c, a, b = p.corner, p.e1, p.e2
    tri_pts = np.where(
        quads[:, None, None],
        np.stack([c, c + a, c + a + b, c, c + a + b, c + b], axis=1),
        np.stack([c, c + a, c + b, c, c, c], axis=1),
    )
    facing = np.round(p.normal * 1e3).astype(np.int64)
    back = (np.arange(n2) >= n2 // 2).astype(np.int64)
    facing[p.sphere_radius > 0] = back[p.sphere_radius > 0, None]  # a sphere: front or back only
    key_pts = np.round(tri_pts / 1e-6).astype(np.int64)
    used = np.ones((n2, 6), dtype=bool)
    used[~quads, 3:] = False  # a triangle has 3 corners
    # one row per (patch, corner): the corner's group (object, facing) and its point; equal rows share
    rows = np.concatenate(
        [np.repeat(np.column_stack([p.obj.astype(np.int64), facing])[:, None, :], 6, axis=1), key_pts], axis=2
    )
    _, inverse = np.unique(rows[used], axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    weight = np.repeat(p.area[:, None], 6, axis=1)[used]
    sums = np.zeros((inverse.max() + 1, 3))
    np.add.at(sums, inverse, weight[:, None] * np.repeat(values[:, None, :], 6, axis=1)[used])
    counts = np.zeros(inverse.max() + 1)
    np.add.at(counts, inverse, weight)
    out = np.zeros((n2, 6, 3))
    out[used] = sums[inverse] / counts[inverse, None]
    return out


def attach(
    cs: CompiledScene,
    device: str = "cpu",
    threads: int | None = None,
    on_step=None,
    cancel=None,
    cache: SolutionCache | None = None,
) -> Solution:
    """Solve the scene's radiosity (render.radiosity settings), or read it from `cache`, and put it in
    cs.data.rad for the kernels; the Solution stays in cs.radiosity (the patches, the convergence
    curve). `on_step` and `cancel` as in `solve`."""
    cfg = cs.scene.render.radiosity
    key = cache.key(cs) if cache is not None else None
    sol = cache.get(key) if cache is not None and key is not None else None
    if sol is None:
        sol = solve(
            cs,
            patch_size=cfg.patch_size,
            rays=cfg.rays,
            threshold=cfg.threshold,
            max_steps=cfg.max_steps,
            seed=cs.scene.render.seed,
            on_step=on_step,
            cancel=cancel,
            threads=threads,
            device=device,
        )
    p = sol.patches
    ix, keep = patch_index(p, device)
    indirect = np.maximum(sol.radiosity - sol.direct, 0.0)
    if sol.corners is None:  # the smooth shading's corner values, kept with a cached solution
        sol.corners = _triangle_corners(ix, p, corner_values(p, sol.radiosity))
        sol.corners_ind = _triangle_corners(ix, p, corner_values(p, indirect))
        if cache is not None and key is not None:
            cache.put(key, sol)
    r = RadiosityData()
    r.active = 1
    r.mode = int(RadDisplay[cfg.display.replace("-", "_").upper()])
    r.index = ix
    r.corners = wp.array(sol.corners, dtype=wp.vec3, device=device)
    r.corners_ind = wp.array(sol.corners_ind, dtype=wp.vec3, device=device)
    r.radiosity = wp.array(sol.radiosity.astype(np.float32), dtype=wp.vec3, device=device)
    r.indirect = wp.array(indirect.astype(np.float32), dtype=wp.vec3, device=device)
    r.rho = wp.array(p.reflectance.astype(np.float32), dtype=wp.vec3, device=device)
    cs.data.rad = r
    cs.keep += keep
    cs.radiosity = sol
    return sol


def _triangle_corners(ix: PatchIndex, p: Patches, corners: np.ndarray) -> np.ndarray:
    """(2 x 3 per triangle of the patch mesh) corner values: every front triangle, then every back one."""
    n = len(p) // 2
    tri_patch = ix.tri_patch.numpy()
    out = []
    for offset in (0, n):
        seen: dict = {}
        for k in tri_patch:
            first = seen.get(int(k), 0)  # a parallelogram's first or second triangle
            out.append(corners[k + offset, 3 * first : 3 * first + 3])
            seen[int(k)] = first + 1
    return np.concatenate(out).astype(np.float32)
