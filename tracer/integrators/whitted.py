"""The recursive ray tree of Whitted (1980) with Phong shading, on an explicit stack.

Warp has no recursion, so each pixel sample keeps its own depth-first stack of pending rays
(origin, direction, weight, depth, kind). Popping a ray: find its closest hit; add its local
term (emission + ka Ia + one shadow ray per point, spot or directional light that can
contribute, `light_samples` stratified shadow rays per area light), then push a reflection ray
of weight kr and a transmission ray of weight kt (times Fresnel's R and 1 - R when asked),
while depth + 1 <= max_depth and the branch weight stays >= min_weight. The pixel sample is
the sum over the tree of (weight x local term); fog, when on, mixes in its colour with
transmittance e^(-density t) along each ray.

With a stochastic sampler, a lens, a shutter, area lights and `gloss`, the same tree is
distribution ray tracing (Cook, Porter & Carpenter 1984): every ray carries a time, shadow
rays sample the area of the lights (penumbrae), and glossy rays are drawn from a cos^m lobe.

With `record` = 1 the same code writes each ray as a node of the ray tree (record.py).
"""

import warp as wp

from tracer.geometry import PI, closest_hit
from tracer.integrators.common import (
    SampleOut,
    fog_transmittance,
    glossy_direction,
    light_sample,
    max3,
    miss_radiance,
    offset_origin,
    scatter_weights,
    shadow_reach,
    shadow_test,
    surface_at,
)
from tracer.integrators.record import (
    F_FOG,
    I_END,
    I_LIGHT,
    I_OCCLUDED,
    V_CARRIED,
    TreeRecord,
    begin_node,
    record_hit,
    record_miss,
    record_terms,
)
from tracer.kinds import (
    END_ABSORBED,
    END_LIGHT,
    END_MAX_DEPTH,
    END_MIN_WEIGHT,
    END_NONE,
    END_TIR,
    RAD_TWO_PASS,
    RAY_EYE,
    RAY_REFLECTION,
    RAY_SHADOW,
    RAY_TRANSMISSION,
    T_FAR,
)
from tracer.lights import is_area_light
from tracer.materials import phong_terms, reflect
from tracer.radiosity import radiosity_at, safe_div
from tracer.sampling import stratum
from tracer.structs import SceneData


@wp.struct
class Stack:
    """Pending rays of each thread's ray tree: row = thread, column = stack slot."""

    o: wp.array2d(dtype=wp.vec3)  # origin
    d: wp.array2d(dtype=wp.vec3)  # unit direction
    k: wp.array2d(dtype=wp.vec3)  # the ray's own K (kr or kt, with Fresnel)
    w: wp.array2d(dtype=wp.vec3)  # product of K's from the eye to this ray
    tau: wp.array2d(dtype=wp.vec3)  # w times the fog transmittance of its ancestors
    i: wp.array2d(dtype=wp.vec3i)  # depth, kind, parent node


@wp.func
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
    st.o[row, sp] = o
    st.d[row, sp] = d
    st.k[row, sp] = k
    st.w[row, sp] = w
    st.tau[row, sp] = tau
    st.i[row, sp] = wp.vec3i(depth, kind, parent)
    return sp + 1


@wp.func
def shadow_node(
    rec: TreeRecord,
    node: int,
    depth: int,
    so: wp.vec3,
    l: wp.vec3,
    w: wp.vec3,
    time: float,
    li: int,
    blocked: int,
    sh_t: float,
    sh_p: wp.vec3,
    sh_ng: wp.vec3,
    sh_obj: int,
    sh_mat: int,
    carried: wp.vec3,
):
    """Record one shadow ray: the occluder it met, or what it carried from the light."""
    if node >= 0:
        sn = begin_node(rec, RAY_SHADOW, depth, node, so, l, w, wp.vec3(1.0), time)
        if sn >= 0:
            rec.ints[sn, I_LIGHT] = li
            rec.ints[sn, I_OCCLUDED] = blocked
            if blocked != 0:
                front = wp.dot(l, sh_ng) < 0.0
                record_hit(rec, sn, sh_t, sh_p, wp.where(front, sh_ng, -sh_ng), sh_obj, sh_mat, wp.where(front, 1, 0))
                rec.ints[sn, I_END] = END_ABSORBED
            else:
                rec.vecs[sn, V_CARRIED] = carried
                rec.ints[sn, I_END] = END_LIGHT


@wp.func
def trace(
    scene: SceneData,
    o: wp.vec3,
    d: wp.vec3,
    time: float,
    rng: wp.uint32,
    st: Stack,
    row: int,
    record: int,
    rec: TreeRecord,
) -> SampleOut:
    """Radiance of the ray tree rooted at the eye ray (o, d) at `time`, its rays by kind, its first hit."""
    out = SampleOut()
    out.color = wp.vec3(0.0)
    out.counts = wp.vec4i(0)
    out.depth = 0.0
    out.normal = wp.vec3(0.0)
    out.albedo = wp.vec3(0.0)
    state = wp.uint32(rng)
    one = wp.vec3(1.0)
    sp = push(st, row, 0, o, d, one, one, one, 1, RAY_EYE, -1)
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
        n = s.n
        if kind == RAY_EYE:
            out.depth = h.t
            out.normal = n
            out.albedo = s.kd
        v = -rd
        ambient = wp.cw_mul(s.ka, scene.ambient)
        diffuse = wp.vec3(0.0)
        specular = wp.vec3(0.0)
        shown = int(0)  # radiosity display modes: the patch's own radiance is the local term
        if scene.rad.active != 0:
            # radiosity: the solution's interreflection replaces the ambient term (two-pass method)
            ambient = wp.vec3(0.0)
            found, rb, rind, rrho = radiosity_at(scene.rad, h.po, s.nf, h.obj)
            if found != 0:
                if scene.rad.mode == RAD_TWO_PASS:
                    ambient = wp.cw_mul(s.kd, safe_div(rind, rrho)) / PI
                else:
                    ambient = rb / PI
                    shown = 1
        if node >= 0:
            record_hit(rec, node, h.t, h.p, n, h.obj, h.mat, s.front)
            rec.floats[node, F_FOG] = fog_t

        # local term: shadow rays towards each light that can contribute here (N.L > 0, inside a spot's cone)
        for li in range(scene.num_lights * (1 - shown)):
            light = scene.lights[li]
            area = is_area_light(light)
            n_rays = wp.where(area, scene.light_samples, 1)
            for k in range(n_rays):
                u = wp.vec2(0.0)
                if area:
                    u = stratum(k, n_rays, wp.randf(state), wp.randf(state))
                l, dist, e, pdf, reaches = light_sample(light, h.p, u, n_rays)
                if reaches != 0 and wp.dot(n, l) > 0.0:
                    so = offset_origin(h.p, s.nf, l)
                    out.counts[RAY_SHADOW] = out.counts[RAY_SHADOW] + 1
                    sh = shadow_test(scene, so, l, shadow_reach(scene, light, so, l, dist), time, record)
                    blocked = sh.hit
                    dterm, sterm = phong_terms(s.kd, m.ks, m.shininess, n, l, v)
                    dterm = wp.cw_mul(e, dterm)
                    sterm = wp.cw_mul(e, sterm)
                    if blocked == 0:
                        diffuse += dterm
                        specular += sterm
                    if node >= 0:
                        shadow_node(
                            rec,
                            node,
                            depth,
                            so,
                            l,
                            w,
                            time,
                            li,
                            blocked,
                            sh.t,
                            sh.p,
                            sh.ng,
                            sh.obj,
                            sh.mat,
                            dterm + sterm,
                        )
        local = s.emission * float(1 - shown) + ambient + diffuse + specular
        out.color += wp.cw_mul(tau, fog_t * local + (1.0 - fog_t) * scene.fog_color)
        if node >= 0:
            record_terms(rec, node, s.emission, ambient, diffuse, specular)

        # secondary rays: reflection (kr) and transmission (kt), Fresnel-weighted on request
        end = END_NONE
        want_r = max3(m.kr) > 0.0
        want_t = max3(m.kt) > 0.0
        if not want_r and not want_t:
            end = END_ABSORBED
        elif depth + 1 > scene.max_depth:
            end = END_MAX_DEPTH
        else:
            kr, kt, tdir, tir = scatter_weights(m, rd, n, s.front)
            wr = wp.cw_mul(w, kr)
            wt = wp.cw_mul(w, kt)
            go_r = max3(wr) > 0.0 and max3(wr) >= scene.min_weight
            go_t = max3(wt) > 0.0 and max3(wt) >= scene.min_weight
            child_tau = tau * fog_t
            if go_t:
                # frosted glass: a direction from the cos^m lobe about the refracted one, kept inside
                gdir = glossy_direction(tdir, m.gloss, wp.randf(state), wp.randf(state))
                if wp.dot(gdir, s.nf) < 0.0 or m.gloss <= 0.0:
                    sp = push(
                        st,
                        row,
                        sp,
                        offset_origin(h.p, s.nf, gdir),
                        gdir,
                        kt,
                        wt,
                        wp.cw_mul(child_tau, kt),
                        depth + 1,
                        RAY_TRANSMISSION,
                        node,
                    )
            if go_r:
                rdir = wp.normalize(reflect(rd, n))
                gdir = glossy_direction(rdir, m.gloss, wp.randf(state), wp.randf(state))
                if wp.dot(gdir, s.nf) > 0.0 or m.gloss <= 0.0:
                    sp = push(
                        st,
                        row,
                        sp,
                        offset_origin(h.p, s.nf, gdir),
                        gdir,
                        kr,
                        wr,
                        wp.cw_mul(child_tau, kr),
                        depth + 1,
                        RAY_REFLECTION,
                        node,
                    )
            if (max3(wr) > 0.0 or max3(wt) > 0.0) and not go_r and not go_t:
                end = END_MIN_WEIGHT
            elif tir != 0:
                end = END_TIR
        if node >= 0:
            rec.ints[node, I_END] = end
    return out
