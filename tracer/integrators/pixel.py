"""A pixel sample: where it goes on the film, its filter weight, its random numbers and its eye ray;
and the film's running sums that the render kernels add it to (dispatch.py, adaptive.py).
"""

import warp as wp

from tracer.kernels.camera import camera_ray, shutter_time
from tracer.kernels.kinds import SAMPLER_LOWDISCREPANCY
from tracer.kernels.sampling import (
    DIM_LENS,
    DIM_TIME,
    film_offset,
    film_uniforms,
    filter_offset,
    pixel_key,
    rng_start,
    sobol_2d,
)
from tracer.kernels.structs import SceneData, struct


@struct
class FilmBuffers:
    """Per-pixel running sums over the samples so far (divide by the sample count)."""

    accum: wp.array2d(dtype=wp.vec3)  # sum of w L (w the filter weight)
    sumsq: wp.array2d(dtype=wp.vec3)  # sum of (w L)^2, for the variance AOV
    counts: wp.array2d(dtype=wp.vec4i)  # rays by RAY_* kind
    depth: wp.array2d(dtype=float)  # sum of the eye rays' hit distances (0 for a miss)
    normal: wp.array2d(dtype=wp.vec3)  # sum of the first hits' shading normals
    albedo: wp.array2d(dtype=wp.vec3)  # sum of the first hits' kd


@wp.func(inline=True)
def band_pixel(scene: SceneData, p0: int, row: int):
    """The pixel of a band's thread `row`, the band starting at pixel p0 (row-major): (x, y, 1), or 0 for a
    thread past the image's last pixel."""
    pix = p0 + row
    return pix % scene.width, pix / scene.width, wp.where(pix < scene.width * scene.height, 1, 0)


@wp.func(inline=True)
def pixel_sample(scene: SceneData, x: int, y: int, s: int):
    """Sample s of pixel (x, y): its film position (filter importance sampled) and weight, its random
    state (after the two draws of the position) and its pixel's low-discrepancy key."""
    key = pixel_key(scene.seed, y * scene.width + x)
    u1, u2, rng = film_uniforms(scene.sampler, key, s, rng_start(scene.seed, y * scene.width + x, s))
    off, weight = filter_offset(scene, film_offset(scene.sampler, s, scene.spp, u1, u2))
    return float(x) + off[0], float(y) + off[1], weight, rng, key


@wp.func(inline=True)
def eye_ray(scene: SceneData, fx: float, fy: float, rng: wp.uint32, key: wp.uint32, sample: int):
    """The eye ray through film position (fx, fy), its lens point and shutter time drawn from rng (the
    time is sample `sample`'s instant when camera.instants is set; the draw is made all the same; the
    lowdiscrepancy sampler takes both from the pixel's sequence, keyed by `key`, the draws made all
    the same): (origin, unit direction, time, rng after its draws)."""
    state = wp.uint32(rng)
    lens1 = wp.randf(state)
    lens2 = wp.randf(state)
    u = wp.randf(state)
    if scene.sampler == SAMPLER_LOWDISCREPANCY:
        if scene.camera.lens_radius > 0.0:
            lens = sobol_2d(key, DIM_LENS, sample)
            lens1 = lens[0]
            lens2 = lens[1]
        if scene.camera.t1 > scene.camera.t0:
            u = sobol_2d(key, DIM_TIME, sample)[0]
    time = shutter_time(scene.camera, u, sample)
    o, d = camera_ray(scene.camera, fx, fy, scene.width, scene.height, lens1, lens2)
    return o, d, time, state
