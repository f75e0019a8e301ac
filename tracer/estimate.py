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

from tracer.scene import AREA_LIGHTS, Scene

RAYS_PER_SECOND = 12.0e6  # per thread, analytic shapes (the examples ran at 5-15 M rays/s on one thread)
SHAPES_HALVE_AT = 40  # the rate halves for every this many analytic shapes (each is tested by every ray)
PASS_SECONDS = 0.01  # fixed cost of one progressive pass (launches, the preview)
SOLVE_RAYS_PER_SECOND = 2.0e6  # radiosity form-factor rays per thread


def rays_per_sample(scene: Scene) -> float:
    """Rays one pixel sample traces, about: eye, reflection and transmission rays (the tree's nodes)
    times one plus the shadow rays at each hit."""
    r = scene.render
    shadow = sum(r.light_samples if isinstance(light, AREA_LIGHTS) else 1 for light in scene.lights)
    materials = [scene.material_for(o) for o in scene.objects]
    specular = any(max(m.kr) > 0 or max(m.kt) > 0 for m in materials)
    if r.integrator == "path":
        nodes = min(r.max_depth, 6)  # Russian roulette ends most paths past depth 5
    else:
        nodes = 1 + (0.3 * min(r.max_depth - 1, 4) if specular else 0)  # most branches end early
    return nodes * (1 + shadow)


def solve_seconds(scene: Scene, threads: int) -> float:
    """The radiosity solve: its shots' rays (patches from the surfaces' area, shots from the threshold)."""
    if scene.render.integrator != "radiosity":
        return 0.0
    cfg = scene.render.radiosity
    area = sum(_area(o) for o in scene.objects)
    sides = 2 * max(1.0, area / cfg.patch_size**2)
    shots = min(cfg.max_steps, 0.3 * sides / 2 * math.log(1 / cfg.threshold) ** 1.5)
    rays = shots * cfg.rays + 256 * sides
    return rays / (SOLVE_RAYS_PER_SECOND * max(1, threads))


def seconds(scene: Scene, threads: int = 1) -> float:
    """Estimated seconds to render `scene` on `threads` threads, the radiosity solve included."""
    film, sampler = scene.film, scene.sampler
    if sampler.type == "adaptive":
        per_pixel = 5 + 12 * sampler.max_level  # corner and centre rays, then cells split at the edges
        passes = sampler.max_level + 1
        eye = film.width * film.height * per_pixel * passes  # each pass traces its levels again
    else:
        eye = film.width * film.height * sampler.spp
        passes = 1 + max(0, math.ceil(math.log2(max(sampler.spp, 1))))
    shapes = sum(1 for o in scene.objects if o.type != "mesh" and o.type != "triangle") + len(scene.lights)
    rate = RAYS_PER_SECOND / (1 + shapes / SHAPES_HALVE_AT) * max(1, threads)
    render = eye * rays_per_sample(scene) / rate + passes * PASS_SECONDS
    return render + solve_seconds(scene, threads)


def _area(o) -> float:
    """An object's surface area (world units^2), for the patch count; meshes and planes as a unit each."""
    import numpy as np

    if o.type == "sphere":
        return 4 * math.pi * o.radius**2
    if o.type == "disk":
        return math.pi * o.radius**2
    if o.type == "quad":
        return float(np.linalg.norm(np.cross(o.edge1, o.edge2)))
    if o.type == "box":
        s = np.subtract(o.max, o.min) * (np.asarray(o.transform.scale) if o.transform else 1.0)
        return float(2 * (s[0] * s[1] + s[1] * s[2] + s[0] * s[2]))
    if o.type == "triangle":
        v = np.asarray(o.vertices)
        return float(np.linalg.norm(np.cross(v[1] - v[0], v[2] - v[0])) / 2)
    return 4.0  # a plane (clipped to the scene), a mesh: a few patches' worth
