"""The recursive ray tree of Whitted (1980) with Phong shading, on an explicit stack.

Warp has no recursion, so each pixel sample keeps its own depth-first stack of pending rays
(origin, direction, weight, depth, kind). Popping a ray: find its closest hit; add its local
term (emission + ka Ia + one shadow ray per point, spot or directional light that can
contribute, `light_samples` stratified shadow rays per area light), then push a reflection ray
of weight kr and a transmission ray of weight kt (times Fresnel's R and 1 - R when asked),
while depth + 1 <= max_depth and the branch weight stays >= min_weight. The pixel sample is
the sum over the tree of (weight x local term); fog, when on, mixes in its colour with
transmittance e^(-density t) along each ray.

Where a material both reflects and transmits, the tree can double with each level (a glass ball in a
box of mirrors, max_depth 64, min_weight 0: nothing else ends it), so a sample's tree has at most
`max_tree_rays` eye, reflection and transmission rays (tracer/limits.py): a child wanted past them is
not traced (end reason END_MAX_TREE_RAYS), depth first, so the same rays in the image and the tree.

With a stochastic sampler, a lens, a shutter, area lights and `gloss`, the same tree is
distribution ray tracing (Cook, Porter & Carpenter 1984): every ray carries a time, shadow
rays sample the area of the lights (penumbrae), and glossy rays are drawn from a cos^m lobe.

With the radiosity integrator the same tree shades with a radiosity solution (tracer/radiosity/lookup.py):
its interreflection in place of the ambient term (the two-pass method), or the patches' own radiance.
With `record` = 1 the same code writes each ray as a node of the ray tree (record.py).
"""

import warp as wp

from tracer.integrators.common import (
    SampleOut,
    Stack,
    fog_transmittance,
    glossy_direction,
    max3,
    miss_radiance,
    no_sample,
    offset_origin,
    scatter_weights,
    surface_at,
)
from tracer.integrators.direct import STRATIFIED, direct_light
from tracer.integrators.record import (
    TreeRecord,
    begin_node,
    record_end,
    record_hit,
    record_miss,
    record_terms,
)
from tracer.kernels.geometry import closest_hit
from tracer.kernels.kinds import (
    END_ABSORBED,
    END_MAX_DEPTH,
    END_MAX_TREE_RAYS,
    END_MIN_WEIGHT,
    END_NONE,
    END_TIR,
    RAY_EYE,
    RAY_REFLECTION,
    RAY_SHADOW,
    RAY_TRANSMISSION,
    T_FAR,
)
from tracer.kernels.materials import reflect
from tracer.kernels.structs import SceneData
from tracer.radiosity.lookup import radiosity_ambient


@wp.func(inline=True)
def push(
    st: Stack,
    row: int,
    sp: int,
    o: wp.vec3,
    d: wp.vec3,
    k: wp.vec3,
    w: wp.vec3,
    tau: wp.vec3,
    depth: int,
    kind: int,
    parent: int,
) -> int:
    """Put the ray (o, d) of RAY_* kind on the stack: its own K, the product of K's w, w times the fog
    transmittance of its ancestors tau, its depth and parent node. Returns the new stack size."""
    st.o[row, sp] = o
    st.d[row, sp] = d
    st.k[row, sp] = k
    st.w[row, sp] = w
    st.tau[row, sp] = tau
    st.i[row, sp] = wp.vec3i(depth, kind, parent)
    return sp + 1


@wp.func(inline=True)
def push_child(
    st: Stack,
    row: int,
    sp: int,
    p: wp.vec3,
    nf: wp.vec3,
    d: wp.vec3,
    k: wp.vec3,
    w: wp.vec3,
    tau: wp.vec3,
    depth: int,
    kind: int,
    parent: int,
) -> int:
    """A secondary ray from hit point p (normal nf) along d, of weight K = k, whose parent's weights are w, tau."""
    return push(st, row, sp, offset_origin(p, nf, d), d, k, wp.cw_mul(w, k), wp.cw_mul(tau, k), depth, kind, parent)


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
    """Radiance of the ray tree rooted at the eye ray (o, d) at `time`, its rays by kind, its first hit.
    Its random numbers come from rng alone (key and sample are the path integrator's)."""
    out = no_sample()
    state = wp.uint32(rng)
    one = wp.vec3(1.0)
    sp = push(st, row, 0, o, d, one, one, one, 1, RAY_EYE, -1)
    rays = int(1)  # tree rays pushed so far (traced or pending): at most scene.max_tree_rays
    while sp > 0:
        sp -= 1
        ro = st.o[row, sp]
        rd = st.d[row, sp]
        w = st.w[row, sp]
        tau = st.tau[row, sp]
        info = st.i[row, sp]
        depth = info[0]
        kind = info[1]
        out.counts[kind] = out.counts[kind] + 1
        node = int(-1)
        if record != 0:
            node = begin_node(rec, kind, depth, info[2], ro, rd, w, st.k[row, sp], time)
        h = closest_hit(scene, ro, rd, T_FAR, time)
        if h.hit == 0:  # the ray leaves the scene
            out.color += wp.cw_mul(tau, miss_radiance(scene))
            record_miss(rec, node, wp.where(scene.fog_density > 0.0, 1, 0))
            continue
        fog_t = fog_transmittance(scene, h.t)
        s = surface_at(scene, h, rd)
        m = s.m
        if kind == RAY_EYE:
            out.depth = h.t
            out.normal = s.n
            out.albedo = s.kd
        record_hit(rec, node, h.t, h.p, s.n, h.obj, h.mat, s.front, fog_t)

        # local term: emission + ka Ia + the lights' direct light; with a radiosity solution its
        # interreflection replaces ka Ia, or (its flat and smooth displays) the patch's own radiance is all
        ambient = wp.cw_mul(s.ka, scene.ambient)
        shown = int(0)
        if scene.rad.active != 0:
            ambient, shown = radiosity_ambient(scene.rad, s.kd, h.po, s.nf, h.obj)
        lights = scene.num_lights * (1 - shown)
        zero = wp.vec3(0.0)  # no BSDF sampling to weigh the light samples against
        diffuse, specular, shadow_rays, state = direct_light(
            scene, s, -rd, time, lights, state, key, STRATIFIED, sample, 0.0, 0.0, zero, record, rec, node, depth, w
        )
        out.counts[RAY_SHADOW] = out.counts[RAY_SHADOW] + shadow_rays
        local = s.emission * float(1 - shown) + ambient + diffuse + specular
        out.color += wp.cw_mul(tau, fog_t * local + (1.0 - fog_t) * scene.fog_color)
        record_terms(rec, node, s.emission, ambient, diffuse, specular)

        # secondary rays: reflection (kr) and transmission (kt), Fresnel-weighted on request
        end = END_NONE
        if not (max3(m.kr) > 0.0 or max3(m.kt) > 0.0):
            end = END_ABSORBED
        elif depth + 1 > scene.max_depth:
            end = END_MAX_DEPTH
        else:
            kr, kt, tdir, tir = scatter_weights(m, rd, s.n, s.front)
            wr = wp.cw_mul(w, kr)
            wt = wp.cw_mul(w, kt)
            go_r = max3(wr) > 0.0 and max3(wr) >= scene.min_weight
            go_t = max3(wt) > 0.0 and max3(wt) >= scene.min_weight
            child_tau = tau * fog_t
            cut = int(0)  # a wanted child left untraced: the tree has its max_tree_rays rays
            if go_t:
                # frosted glass: a direction from the cos^m lobe about the refracted one, kept inside
                gdir = glossy_direction(tdir, m.gloss, wp.randf(state), wp.randf(state))
                inside = wp.dot(gdir, s.nf) < 0.0 or m.gloss <= 0.0
                if inside and rays >= scene.max_tree_rays:
                    cut = 1
                elif inside:
                    sp = push_child(st, row, sp, h.p, s.nf, gdir, kt, w, child_tau, depth + 1, RAY_TRANSMISSION, node)
                    rays += 1
            if go_r:
                rdir = wp.normalize(reflect(rd, s.n))
                gdir = glossy_direction(rdir, m.gloss, wp.randf(state), wp.randf(state))
                outside = wp.dot(gdir, s.nf) > 0.0 or m.gloss <= 0.0
                if outside and rays >= scene.max_tree_rays:
                    cut = 1
                elif outside:
                    sp = push_child(st, row, sp, h.p, s.nf, gdir, kr, w, child_tau, depth + 1, RAY_REFLECTION, node)
                    rays += 1
            if cut != 0:
                end = END_MAX_TREE_RAYS
            elif (max3(wr) > 0.0 or max3(wt) > 0.0) and not go_r and not go_t:
                end = END_MIN_WEIGHT
            elif tir != 0:
                end = END_TIR
        record_end(rec, node, end)
    return out
