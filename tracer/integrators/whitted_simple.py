"""Whitted's ray tracer in lecture size: the lecture's Shade(), for reading beside whitted.py.

    Shade(ray, depth) = emission + ka Ia + sum over lights (shadow ray) of the Phong term
                        + kr Shade(reflected, depth + 1) + kt Shade(transmitted, depth + 1)

Warp has no recursion, so the pending calls of Shade() wait on a stack: each entry is a ray with
its weight w (the product of the kr's and kt's from the eye down to it) and its depth, and the
pixel sample's radiance is the sum over the tree of w x local term. The transmission ray is pushed
first, so the reflection ray is traced first: the same order, hence the same sums and the same
random numbers, as whitted.py.

This is whitted.py without what a lecture leaves out: no ray-tree recording (`record`, `rec` are
ignored), no fog, no radiosity ambient, no `max_tree_rays` cap. On a scene without fog or a
radiosity solution, whose trees stay under the cap, it renders the same image, bit for bit
(tests/tracer/test_whitted_simple.py). It is not in the integrator table: no scene selects it,
and the service renders with whitted.py; `dispatch.make_kernels(trace, ...)` renders with it.
"""

import warp as wp

from tracer.integrators.common import (
    SampleOut,
    Stack,
    glossy_direction,
    max3,
    no_sample,
    offset_origin,
    scatter_weights,
    surface_at,
)
from tracer.integrators.direct import STRATIFIED, direct_light
from tracer.integrators.record import TreeRecord
from tracer.kernels.geometry import closest_hit
from tracer.kernels.kinds import RAY_EYE, RAY_REFLECTION, RAY_SHADOW, RAY_TRANSMISSION, T_FAR
from tracer.kernels.materials import reflect
from tracer.kernels.structs import SceneData


@wp.func(inline=True)
def push(st: Stack, row: int, sp: int, o: wp.vec3, d: wp.vec3, w: wp.vec3, depth: int, kind: int) -> int:
    """A call of Shade() to make later: the ray (o, d) of RAY_* kind, its weight w and depth."""
    st.o[row, sp] = o
    st.d[row, sp] = d
    st.w[row, sp] = w
    st.i[row, sp] = wp.vec3i(depth, kind, -1)
    return sp + 1


@wp.func(inline=True)
def trace(
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
    """Radiance of the ray tree rooted at the eye ray (o, d) at `time`, its rays by kind, its first hit."""
    out = no_sample()
    state = wp.uint32(rng)  # random numbers for area lights and glossy rays (distribution ray tracing)
    sp = push(st, row, 0, o, d, wp.vec3(1.0), 1, RAY_EYE)
    while sp > 0:
        sp -= 1  # Shade(ray, depth):
        rd = st.d[row, sp]
        w = st.w[row, sp]
        depth = st.i[row, sp][0]
        kind = st.i[row, sp][1]
        out.counts[kind] = out.counts[kind] + 1
        h = closest_hit(scene, st.o[row, sp], rd, T_FAR, time)
        if h.hit == 0:  # the ray leaves the scene
            out.color += wp.cw_mul(w, scene.background)
            continue
        s = surface_at(scene, h, rd)
        if depth == 1:  # the eye ray's hit, for the AOVs
            out.depth = h.t
            out.normal = s.n
            out.albedo = s.kd
        # local term: emission + ka Ia + one shadow ray per light (light_samples per area light)
        zero = wp.vec3(0.0)  # (no BSDF sampling to weigh the light samples against: the path integrator's)
        diffuse, specular, shadow_rays, state = direct_light(
            scene, s, -rd, time, scene.num_lights, state, key, STRATIFIED, sample, 0.0, 0.0, zero, 0, rec, -1, depth, w
        )
        out.counts[RAY_SHADOW] = out.counts[RAY_SHADOW] + shadow_rays
        out.color += wp.cw_mul(w, s.emission + wp.cw_mul(s.ka, scene.ambient) + diffuse + specular)
        if depth + 1 > scene.max_depth:
            continue
        # + kt Shade(transmitted) + kr Shade(reflected): kr, kt with Fresnel on request, TIR's kt to kr
        kr, kt, tdir, tir = scatter_weights(s.m, rd, s.n, s.front)
        wr, wt = wp.cw_mul(w, kr), wp.cw_mul(w, kt)
        if max3(wt) > 0.0 and max3(wt) >= scene.min_weight:  # gloss: a direction from the lobe, kept inside
            t = glossy_direction(tdir, s.m.gloss, wp.randf(state), wp.randf(state))
            if wp.dot(t, s.nf) < 0.0 or s.m.gloss <= 0.0:
                sp = push(st, row, sp, offset_origin(h.p, s.nf, t), t, wt, depth + 1, RAY_TRANSMISSION)
        if max3(wr) > 0.0 and max3(wr) >= scene.min_weight:  # gloss: the same about the mirror direction
            r = glossy_direction(wp.normalize(reflect(rd, s.n)), s.m.gloss, wp.randf(state), wp.randf(state))
            if wp.dot(r, s.nf) > 0.0 or s.m.gloss <= 0.0:
                sp = push(st, row, sp, offset_origin(h.p, s.nf, r), r, wr, depth + 1, RAY_REFLECTION)
    return out
