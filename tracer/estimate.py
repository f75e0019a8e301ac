"""How long a render will take, before it starts: a cost model of rays, for the service's queue.

The service uses it to put long renders in the batch lane, to tell a student the expected wait, and
to refuse at submit a render that could not finish within the per-job limit. It counts the rays a
pixel sample will trace (the eye ray, the shadow rays at each hit, the reflection and transmission
rays of the ray tree, a path's bounces) and the radiosity solve's form-factor rays, and turns them
into seconds with a rate per thread measured on the example scenes (BENCHMARKS.md). It errs on the
long side; the service scales it by what finished jobs actually took.
"""

from __future__ import annotations

import math
from pathlib import Path

from tracer import meshing
from tracer.scene import AREA_LIGHTS, Scene

RAYS_PER_SECOND = 12.0e6  # per thread, analytic shapes (the examples ran at 5-15 M rays/s on one thread)
SHAPES_HALVE_AT = 40  # the rate halves for every this many analytic shapes (each is tested by every ray)
PASS_SECONDS = 0.01  # fixed cost of one progressive pass (launches, the preview)
SOLVE_RAYS_PER_SECOND = 2.0e6  # radiosity form-factor rays per thread
LIGHT_RAYS_PER_SIDE = 256  # an area light's shot: at least this many rays per patch side (radiosity/solver.py)


def rays_per_sample(scene: Scene) -> float:
    """Rays one pixel sample traces, about: eye, reflection and transmission rays (the tree's nodes)
    times one plus the shadow rays at each hit."""
    r = scene.render
    shadow = sum(r.light_samples if isinstance(light, AREA_LIGHTS) else 1 for light in scene.lights)
    materials = [scene.material_for(o) for o in scene.objects]
    specular = any(max(m.kr) > 0 or max(m.kt) > 0 for m in materials)
    if r.integrator_info.cost == "path":
        nodes = min(r.max_depth, 6)  # Russian roulette ends most paths past depth 5
    else:
        nodes = 1 + (0.3 * min(r.max_depth - 1, 4) if specular else 0)  # most branches end early
    return nodes * (1 + shadow)


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


def seconds(scene: Scene, threads: int = 1, assets: Path | None = None, solve: float | None = None) -> float:
    """Estimated seconds to render `scene` on `threads` threads, the radiosity solve included (`assets`:
    the folder of its mesh files, for the solve's patches; `solve`: the solve's seconds, when known)."""
    film, sampler = scene.film, scene.sampler
    if sampler.type == "adaptive":
        per_pixel = 5 + 12 * sampler.max_level  # corner and centre rays, then cells split at the edges
        passes = sampler.max_level + 1
        eye = film.width * film.height * per_pixel  # each grid point once over all the passes
    else:
        eye = film.width * film.height * sampler.spp
        passes = 1 + max(0, math.ceil(math.log2(max(sampler.spp, 1))))
    shapes = sum(1 for o in scene.objects if o.type != "mesh" and o.type != "triangle") + len(scene.lights)
    rate = RAYS_PER_SECOND / (1 + shapes / SHAPES_HALVE_AT) * max(1, threads)
    render = eye * rays_per_sample(scene) / rate + passes * PASS_SECONDS
    return render + (solve_seconds(scene, threads, assets) if solve is None else solve)
