"""The render kernels: thread -> pixel -> sample -> RNG -> camera ray -> the scene's integrator.

`render_rows` adds samples s0..s1-1 of every pixel of a band of rows to the film's running sums
(one thread per pixel, samples in order, so any split into passes gives the same sums);
`trace_one` traces one pixel sample with its ray tree recorded.
"""

import warp as wp

from tracer.camera import camera_ray, shutter_time
from tracer.compile import SceneData
from tracer.integrators import path, whitted
from tracer.integrators.common import SampleOut
from tracer.integrators.record import TreeRecord
from tracer.kinds import INTEGRATOR_PATH
from tracer.sampling import film_offset, filter_offset, rng_start


@wp.struct
class FilmBuffers:
    """Per-pixel running sums over the samples so far (divide by the sample count)."""

    accum: wp.array2d(dtype=wp.vec3)  # sum of w L (w the filter weight)
    sumsq: wp.array2d(dtype=wp.vec3)  # sum of (w L)^2, for the variance AOV
    counts: wp.array2d(dtype=wp.vec4i)  # rays by RAY_* kind
    depth: wp.array2d(dtype=float)  # sum of the eye rays' hit distances (0 for a miss)
    normal: wp.array2d(dtype=wp.vec3)  # sum of the first hits' shading normals
    albedo: wp.array2d(dtype=wp.vec3)  # sum of the first hits' kd


@wp.func
def trace_sample(scene: SceneData, x: int, y: int, s: int, st: whitted.Stack, row: int, record: int, rec: TreeRecord):
    """Sample s of pixel (x, y): film position (filter importance sampled), lens point, time, and the
    integrator's estimate. Returns the sample (its radiance already times the filter weight) and the weight."""
    rng = rng_start(scene.seed, y * scene.width + x, s)
    u1 = wp.randf(rng)
    u2 = wp.randf(rng)
    off, weight = filter_offset(scene, film_offset(scene.sampler, s, scene.spp, u1, u2))
    lens1 = wp.randf(rng)
    lens2 = wp.randf(rng)
    time = shutter_time(scene.camera, wp.randf(rng))
    o, d = camera_ray(scene.camera, float(x) + off[0], float(y) + off[1], scene.width, scene.height, lens1, lens2)
    out = SampleOut()
    if scene.integrator == INTEGRATOR_PATH:
        out = path.trace(scene, o, d, time, rng, record, rec)
    else:
        out = whitted.trace(scene, o, d, time, rng, st, row, record, rec)
    out.color = out.color * weight
    return out, weight


@wp.kernel
def render_rows(scene: SceneData, y0: int, s0: int, s1: int, st: whitted.Stack, rec: TreeRecord, film: FilmBuffers):
    """Add samples s0..s1-1 of each pixel of rows y0.. to the film's sums (one thread per pixel)."""
    row = wp.tid()
    x = row % scene.width
    y = y0 + row / scene.width
    if y >= scene.height:
        return
    acc = film.accum[y, x]
    sq = film.sumsq[y, x]
    cnt = film.counts[y, x]
    dep = film.depth[y, x]
    nrm = film.normal[y, x]
    alb = film.albedo[y, x]
    for s in range(s0, s1):
        out, weight = trace_sample(scene, x, y, s, st, row, 0, rec)
        acc = acc + out.color
        sq = sq + wp.cw_mul(out.color, out.color)
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


@wp.kernel
def trace_one(
    scene: SceneData, x: int, y: int, s: int, st: whitted.Stack, rec: TreeRecord, out: wp.array(dtype=wp.vec3)
):
    """One pixel sample with its ray tree recorded."""
    r, weight = trace_sample(scene, x, y, s, st, 0, 1, rec)
    out[0] = r.color
    out[1] = wp.vec3(weight, 0.0, 0.0)
