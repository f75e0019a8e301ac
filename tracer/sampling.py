"""Random numbers keyed by (seed, pixel, sample), and the pure sample warps.

Only kernels create RNG state: ``rng_start(seed, pixel, sample)`` hashes the key into a PCG
state, and each later draw (``wp.randf``) is the next dimension of that sample. An image
therefore never depends on threads, tiles or how samples are split into passes.
Warps take their uniform numbers as arguments (u1, u2 in [0, 1)), so tests can call them
with chosen values.
"""

import warp as wp

from tracer.kinds import SAMPLER_CENTER, SAMPLER_GRID, SAMPLER_RANDOM

PCG_MUL = wp.constant(wp.uint32(747796405))
PCG_INC = wp.constant(wp.uint32(2891336453))
PCG_OUT = wp.constant(wp.uint32(277803737))


@wp.func
def pcg_hash(v: wp.uint32) -> wp.uint32:
    """PCG-RXS-M-XS hash (Jarzynski & Olano 2020, 'Hash Functions for GPU Rendering')."""
    state = v * PCG_MUL + PCG_INC
    word = ((state >> ((state >> wp.uint32(28)) + wp.uint32(4))) ^ state) * PCG_OUT
    return (word >> wp.uint32(22)) ^ word


@wp.func
def rng_start(seed: int, pixel: int, sample: int) -> wp.uint32:
    """RNG state of one pixel sample; the n-th wp.randf of it is dimension n."""
    h = pcg_hash(wp.uint32(seed))
    h = pcg_hash(h ^ wp.uint32(pixel))
    h = pcg_hash(h ^ wp.uint32(sample))
    return h


@wp.func
def film_offset(sampler: int, sample: int, spp: int, u1: float, u2: float) -> wp.vec2:
    """Position (u, v) in [0,1)^2 inside the pixel of sample `sample` of `spp`.

    center: the pixel centre; grid: centres of a sqrt(spp) x sqrt(spp) grid; random: (u1, u2);
    jittered: one random point in each grid cell (stratified, Cook 1986).
    """
    if sampler == SAMPLER_CENTER:
        return wp.vec2(0.5, 0.5)
    if sampler == SAMPLER_RANDOM:
        return wp.vec2(u1, u2)
    n = int(wp.floor(wp.sqrt(float(spp)) + 0.5))
    i = sample % n
    j = sample / n
    if sampler == SAMPLER_GRID:
        return wp.vec2((float(i) + 0.5) / float(n), (float(j) + 0.5) / float(n))
    return wp.vec2((float(i) + u1) / float(n), (float(j) + u2) / float(n))


@wp.func
def box_filter_offset(uv: wp.vec2, radius: float) -> wp.vec2:
    """Filter importance sampling of a box of half-width `radius` pixels around the pixel centre."""
    return wp.vec2(0.5 + (uv[0] - 0.5) * 2.0 * radius, 0.5 + (uv[1] - 0.5) * 2.0 * radius)
