"""How long a render will take, before it starts: a cost model of rays, for the service's queue.

The service uses it to put long renders in the batch lane, to tell a student the expected wait, and
to refuse at submit a render that could not finish within the per-job limit. It counts the rays a
pixel sample will trace (the eye ray, the shadow rays at each hit, the reflection and transmission
rays of the ray tree, a path's bounces) and the radiosity solve's form-factor rays, and turns them
into seconds with a rate per thread measured on the example scenes (BENCHMARKS.md). It errs on the
long side; the service scales it by what finished jobs actually took.

A ray tree is counted as a branching process up to its bound: each ray spawns on average the children
the scene's materials spawn (2 where kr and kt are both on, 1 where one is, 0 where neither), each
object taken as likely to be hit as any other, level after level to max_depth (fewer where min_weight
ends every branch sooner), and never more than max_tree_rays (tracer/limits.py), the bound the kernel
keeps. A glass ball in a box of mirrors with max_depth 64 and min_weight 0 is counted at that bound.
The adaptive sampler is counted from its grid: with threshold 0 every cell that is not flat is split
to max_level; a larger threshold stops a smooth region's cells sooner, an edge's never.
"""

from __future__ import annotations

import math
from pathlib import Path

from tracer import meshing
from tracer.limits import Limits
from tracer.scene import AREA_LIGHTS, Scene

RAYS_PER_SECOND = 12.0e6  # per thread, analytic shapes (the examples ran at 5-15 M rays/s on one thread)
SHAPES_HALVE_AT = 40  # the rate halves for every this many analytic shapes (each is tested by every ray)
PASS_SECONDS = 0.01  # fixed cost of one progressive pass (launches, the preview)
SOLVE_RAYS_PER_SECOND = 2.0e6  # radiosity form-factor rays per thread
LIGHT_RAYS_PER_SIDE = 256  # an area light's shot: at least this many rays per patch side (radiosity/solver.py)
SMOOTH_GRADIENT = 0.05  # adaptive: the colour change across a pixel of a smoothly shaded surface, about
EDGE_POINTS_PER_LEVEL = 12  # adaptive: grid points per pixel and level where cells are split at the edges


def tree_rays(scene: Scene, max_tree_rays: int | None = None) -> float:
    """Eye, reflection and transmission rays of one pixel sample's ray tree, about: a branching process
    of m children per ray (the objects' materials' children, 2 where kr and kt are on, each object as likely
    to be hit), over the levels max_depth and min_weight allow, at most `max_tree_rays` (the limit's
    default when None): the bound the kernel keeps."""
    bound = Limits().max_tree_rays if max_tree_rays is None else max_tree_rays
    materials = [scene.material_for(o) for o in scene.objects]
    if not materials:
        return 1.0
    children = [(max(m.kr) > 0) + (max(m.kt) > 0) for m in materials]
    m = sum(children) / (len(materials) + sum(1 for light in scene.lights if isinstance(light, AREA_LIGHTS)))
    levels = tree_levels(scene)
    nodes = float(levels) if m == 1 else (m**levels - 1) / (m - 1)  # 1 + m + m^2 + ... (m <= 2: no overflow)
    return min(nodes, float(bound))


def tree_levels(scene: Scene) -> int:
    """Levels a ray tree can have: max_depth, fewer where min_weight ends every branch sooner (a child's
    weight is at most k^(level - 1), k the largest K of a child: kr, kt, or kr + kt under total internal
    reflection without Fresnel)."""
    r = scene.render
    materials = [scene.material_for(o) for o in scene.objects]
    k = max((max(max(mt.kr) + (0 if mt.fresnel else max(mt.kt)), max(mt.kt)) for mt in materials), default=0.0)
    if 0 < k < 1 and r.min_weight > 0:
        return min(r.max_depth, 1 + math.floor(math.log(r.min_weight) / math.log(k)))
    return r.max_depth


def most_rays_per_sample(scene: Scene, max_tree_rays: int | None = None) -> int:
    """The most rays one pixel sample can trace: every ray its tree could have (two children a ray where a
    material reflects and transmits, over tree_levels), at most `max_tree_rays`, times one plus the shadow
    rays at each hit; a path's bounces, each with its shadow rays and one more. tracer/rendering/progressive.py
    sizes its launches by it."""
    r = scene.render
    bound = Limits().max_tree_rays if max_tree_rays is None else max_tree_rays
    shadow = sum(r.light_samples if isinstance(light, AREA_LIGHTS) else 1 for light in scene.lights)
    if r.integrator_info.cost == "path":
        return r.max_depth * (2 + shadow)
    children = max(((max(m.kr) > 0) + (max(m.kt) > 0) for m in map(scene.material_for, scene.objects)), default=0)
    levels = tree_levels(scene)
    possible = 1 if children == 0 else levels if children == 1 else (1 << min(levels, 40)) - 1
    return min(possible, bound) * (1 + shadow)


def rays_per_sample(scene: Scene, max_tree_rays: int | None = None) -> float:
    """Rays one pixel sample traces, about: eye, reflection and transmission rays (the tree's nodes, at
    most `max_tree_rays`) times one plus the shadow rays at each hit."""
    r = scene.render
    shadow = sum(r.light_samples if isinstance(light, AREA_LIGHTS) else 1 for light in scene.lights)
    if r.integrator_info.cost == "path":
        nodes = min(r.max_depth, 6)  # Russian roulette ends most paths past depth 5
    else:
        nodes = tree_rays(scene, max_tree_rays)
    return nodes * (1 + shadow)


def adaptive_points(threshold: float, max_level: int) -> float:
    """Grid points the adaptive sampler traces per pixel, about: the cells of a smooth region split while
    their colour spread (SMOOTH_GRADIENT x their size) passes the threshold, all of them down to max_level
    with threshold 0 (the bound: adaptive.kept_points(max_level)), and those at the edges at every level."""
    full = ((1 << max_level) + 1) ** 2 + (1 << (2 * max_level))  # adaptive.kept_points: every cell split
    smooth = max_level if threshold <= 0 else min(max_level, max(0, math.floor(math.log2(SMOOTH_GRADIENT / threshold))))
    split = ((1 << smooth) + 1) ** 2 + (1 << (2 * smooth))
    return min(full, split + EDGE_POINTS_PER_LEVEL * max_level)


def solve_seconds(scene: Scene, threads: int, assets: Path | None = None) -> float:
    """The radiosity solve: its shots' rays (the patches the surfaces are cut into, tracer/meshing.py, mesh
    files included when `assets` is their folder; the shots from the threshold)."""
    if scene.render.integrator_info.prepass != "radiosity":
        return 0.0
    cfg = scene.render.radiosity
    triangles = meshing.mesh_triangles(scene.objects, meshing.mesh_files(assets))
    patches = sum(meshing.patch_counts(scene, cfg.patch_size, triangles).values())
    sides = 2 * max(1.0, patches)
    shots = min(cfg.max_steps, 0.3 * sides / 2 * math.log(1 / cfg.threshold) ** 1.5)
    rays = shots * cfg.rays + LIGHT_RAYS_PER_SIDE * sides
    return rays / (SOLVE_RAYS_PER_SECOND * max(1, threads))


def seconds(
    scene: Scene, threads: int = 1, assets: Path | None = None, solve: float | None = None, limits: Limits | None = None
) -> float:
    """Estimated seconds to render `scene` on `threads` threads, the radiosity solve included (`assets`:
    the folder of its mesh files, for the solve's patches; `solve`: the solve's seconds, when known;
    `limits`: the service's, whose max_tree_rays bounds a sample's tree)."""
    film, sampler = scene.film, scene.sampler
    if sampler.type == "adaptive":
        per_pixel = adaptive_points(sampler.threshold, sampler.max_level)
        passes = sampler.max_level + 1
        eye = film.width * film.height * per_pixel  # each grid point once over all the passes
    else:
        assert sampler.spp is not None, "the Sampler's validator fills in its type's default spp"
        eye = film.width * film.height * sampler.spp
        passes = 1 + max(0, math.ceil(math.log2(max(sampler.spp, 1))))
    shapes = sum(1 for o in scene.objects if o.type != "mesh" and o.type != "triangle") + len(scene.lights)
    rate = RAYS_PER_SECOND / (1 + shapes / SHAPES_HALVE_AT) * max(1, threads)
    bound = (limits or Limits()).max_tree_rays
    render = eye * rays_per_sample(scene, bound) / rate + passes * PASS_SECONDS
    return render + (solve_seconds(scene, threads, assets) if solve is None else solve)
