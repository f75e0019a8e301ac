"""The recursive ray tree of Whitted (1980) with Phong shading, on an explicit stack.

Warp has no recursion, so each pixel sample keeps its own depth-first stack of pending rays
(origin, direction, weight, depth, kind). Popping a ray: find its closest hit; add its local
term (emission + ka Ia + one shadow ray per light that can contribute), then push a
reflection ray of weight kr and a transmission ray of weight kt (times Fresnel's R and 1 - R
when asked), while depth + 1 <= max_depth and the branch weight stays >= min_weight.
The pixel sample is the sum over the tree of (weight x local term); fog, when on, mixes in
its colour with transmittance e^(-density t) along each ray.

With `record` = 1 the same code writes each ray as a node of the ray tree (tracer/raytree.py
reads it): the tree is never a separate re-implementation of the image.
"""

import warp as wp

from tracer.camera import camera_ray
from tracer.compile import SceneData
from tracer.geometry import closest_hit
from tracer.kinds import (
    END_ABSORBED,
    END_LIGHT,
    END_MAX_DEPTH,
    END_MIN_WEIGHT,
    END_MISS,
    END_NONE,
    END_TIR,
    RAY_EYE,
    RAY_OFFSET,
    RAY_REFLECTION,
    RAY_SHADOW,
    RAY_TRANSMISSION,
    T_FAR,
)
from tracer.lights import light_at
from tracer.materials import bump_normal, diffuse_color, fresnel_dielectric, phong_terms, reflect, refract
from tracer.sampling import box_filter_offset, film_offset, rng_start

# Node record layout (tracer/raytree.py decodes it): integers, vectors and floats per node.
I_KIND, I_DEPTH, I_PARENT, I_HIT, I_OBJ, I_MAT, I_FRONT, I_LIGHT, I_OCCLUDED, I_END = range(10)
V_ORIGIN, V_DIR, V_POINT, V_NORMAL, V_WEIGHT, V_AMBIENT, V_DIFFUSE, V_SPECULAR, V_EMISSION, V_CARRIED, V_K = range(11)
F_T, F_FOG = range(2)
NUM_I, NUM_V, NUM_F = 10, 11, 2


@wp.struct
class Stack:
    """Pending rays of each thread's ray tree: row = thread, column = stack slot."""

    o: wp.array2d(dtype=wp.vec3)  # origin
    d: wp.array2d(dtype=wp.vec3)  # unit direction
    k: wp.array2d(dtype=wp.vec3)  # the ray's own K (kr or kt, with Fresnel)
    w: wp.array2d(dtype=wp.vec3)  # product of K's from the eye to this ray
    tau: wp.array2d(dtype=wp.vec3)  # w times the fog transmittance of its ancestors
    i: wp.array2d(dtype=wp.vec3i)  # depth, kind, parent node


@wp.struct
class TreeRecord:
    """Where `trace` writes the nodes of one sample's tree (record = 1), or a dummy."""

    count: wp.array(dtype=wp.int32)  # [0]: nodes written (may exceed cap: truncated)
    cap: int
    ints: wp.array2d(dtype=wp.int32)  # (cap, NUM_I)
    vecs: wp.array2d(dtype=wp.vec3)  # (cap, NUM_V)
    floats: wp.array2d(dtype=wp.float32)  # (cap, NUM_F)


@wp.func
def begin_node(
    rec: TreeRecord, kind: int, depth: int, parent: int, o: wp.vec3, d: wp.vec3, w: wp.vec3, k: wp.vec3
) -> int:
    node = wp.atomic_add(rec.count, 0, 1)
    if node >= rec.cap:
        return -1
    rec.ints[node, I_KIND] = kind
    rec.ints[node, I_DEPTH] = depth
    rec.ints[node, I_PARENT] = parent
    rec.ints[node, I_HIT] = 0
    rec.ints[node, I_OBJ] = -1
    rec.ints[node, I_MAT] = -1
    rec.ints[node, I_LIGHT] = -1
    rec.ints[node, I_OCCLUDED] = -1
    rec.ints[node, I_END] = END_NONE
    rec.vecs[node, V_ORIGIN] = o
    rec.vecs[node, V_DIR] = d
    rec.vecs[node, V_WEIGHT] = w
    rec.vecs[node, V_K] = k
    for j in range(V_POINT, V_K):
        if j != V_WEIGHT:
            rec.vecs[node, j] = wp.vec3(0.0)
    rec.floats[node, F_T] = -1.0
    rec.floats[node, F_FOG] = 1.0
    return node


@wp.func
def record_hit(rec: TreeRecord, node: int, t: float, p: wp.vec3, n: wp.vec3, obj: int, mat: int, front: int):
    if node >= 0:
        rec.ints[node, I_HIT] = 1
        rec.ints[node, I_OBJ] = obj
        rec.ints[node, I_MAT] = mat
        rec.ints[node, I_FRONT] = front
        rec.floats[node, F_T] = t
        rec.vecs[node, V_POINT] = p
        rec.vecs[node, V_NORMAL] = n


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
def max3(v: wp.vec3) -> float:
    return wp.max(v[0], wp.max(v[1], v[2]))


@wp.func
def offset_origin(p: wp.vec3, nf: wp.vec3, d: wp.vec3) -> wp.vec3:
    """hit + 1e-4 N, N the normal turned to the side that the new ray d travels into."""
    if wp.dot(nf, d) < 0.0:
        return p - RAY_OFFSET * nf
    return p + RAY_OFFSET * nf


@wp.func
def trace(scene: SceneData, o: wp.vec3, d: wp.vec3, st: Stack, row: int, record: int, rec: TreeRecord):
    """Radiance of the ray tree rooted at the eye ray (o, d), and its rays by RAY_* kind."""
    color = wp.vec3(0.0)
    counts = wp.vec4i(0)
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
        counts[kind] = counts[kind] + 1
        node = int(-1)
        if record != 0:
            node = begin_node(rec, kind, depth, info[2], ro, rd, w, st.k[row, sp])
        h = closest_hit(scene, ro, rd, T_FAR)
        if h.hit == 0:
            # a ray that leaves the scene returns the background, or the fog colour in fog
            leave = scene.background
            if scene.fog_density > 0.0:
                leave = scene.fog_color
            color += wp.cw_mul(tau, leave)
            if node >= 0:
                rec.ints[node, I_END] = END_MISS
                rec.floats[node, F_FOG] = wp.where(scene.fog_density > 0.0, 0.0, 1.0)
            continue
        fog_t = float(1.0)
        if scene.fog_density > 0.0:
            fog_t = wp.exp(-scene.fog_density * h.t)
        m = scene.materials[h.mat]
        front = wp.dot(rd, h.ng) < 0.0
        nf = wp.where(front, h.ng, -h.ng)  # the geometric normal turned towards the incoming ray
        n = bump_normal(scene, m, h.p, wp.where(front, h.ns, -h.ns), h.uv, h.dpdu, h.dpdv)
        kd = diffuse_color(scene, m, h.p, h.ng, h.uv)
        ka = wp.where(m.ka_is_kd != 0, kd, m.ka)
        v = -rd
        emission = wp.where(front, m.emission, wp.vec3(0.0))
        ambient = wp.cw_mul(ka, scene.ambient)
        diffuse = wp.vec3(0.0)
        specular = wp.vec3(0.0)
        if node >= 0:
            record_hit(rec, node, h.t, h.p, n, h.obj, h.mat, wp.where(front, 1, 0))
            rec.floats[node, F_FOG] = fog_t

        # local term: one shadow ray per light that can contribute here (N.L > 0, inside a spot's cone)
        for li in range(scene.num_lights):
            l, dist, e, reaches = light_at(scene.lights[li], h.p)
            if reaches != 0 and wp.dot(n, l) > 0.0:
                so = offset_origin(h.p, nf, l)
                counts[RAY_SHADOW] = counts[RAY_SHADOW] + 1
                sh = closest_hit(scene, so, l, dist)
                dterm, sterm = phong_terms(kd, m.ks, m.shininess, n, l, v)
                dterm = wp.cw_mul(e, dterm)
                sterm = wp.cw_mul(e, sterm)
                if sh.hit == 0:
                    diffuse += dterm
                    specular += sterm
                if node >= 0:
                    sn = begin_node(rec, RAY_SHADOW, depth, node, so, l, w, one)
                    if sn >= 0:
                        rec.ints[sn, I_LIGHT] = li
                        rec.ints[sn, I_OCCLUDED] = sh.hit
                        if sh.hit != 0:
                            shf = wp.where(wp.dot(l, sh.ng) < 0.0, sh.ng, -sh.ng)
                            record_hit(rec, sn, sh.t, sh.p, shf, sh.obj, sh.mat, wp.where(wp.dot(l, sh.ng) < 0.0, 1, 0))
                            rec.ints[sn, I_END] = END_ABSORBED
                        else:
                            rec.vecs[sn, V_CARRIED] = dterm + sterm
                            rec.ints[sn, I_END] = END_LIGHT
        local = emission + ambient + diffuse + specular
        color += wp.cw_mul(tau, fog_t * local + (1.0 - fog_t) * scene.fog_color)
        if node >= 0:
            rec.vecs[node, V_EMISSION] = emission
            rec.vecs[node, V_AMBIENT] = ambient
            rec.vecs[node, V_DIFFUSE] = diffuse
            rec.vecs[node, V_SPECULAR] = specular

        # secondary rays: reflection (kr) and transmission (kt), Fresnel-weighted on request
        end = END_NONE
        want_r = max3(m.kr) > 0.0
        want_t = max3(m.kt) > 0.0
        if not want_r and not want_t:
            end = END_ABSORBED
        elif depth + 1 > scene.max_depth:
            end = END_MAX_DEPTH
        else:
            eta = wp.where(front, 1.0 / m.ior, m.ior)  # n_incident / n_transmitted
            kr = m.kr
            kt = m.kt
            tdir = wp.vec3(0.0)
            tir = int(0)
            if want_t:
                tdir, refracted = refract(rd, n, eta)
                tir = 1 - refracted
            if m.fresnel != 0:
                r = fresnel_dielectric(-wp.dot(rd, n), eta)
                if tir != 0:
                    r = 1.0
                kr = kr * r
                kt = kt * (1.0 - r)
            if tir != 0:
                if m.fresnel == 0:
                    kr = kr + kt  # the transmission ray's weight goes to the reflection ray
                kt = wp.vec3(0.0)
            wr = wp.cw_mul(w, kr)
            wt = wp.cw_mul(w, kt)
            go_r = max3(wr) > 0.0 and max3(wr) >= scene.min_weight
            go_t = max3(wt) > 0.0 and max3(wt) >= scene.min_weight
            child_tau = tau * fog_t
            if go_t:
                sp = push(
                    st,
                    row,
                    sp,
                    offset_origin(h.p, nf, tdir),
                    tdir,
                    kt,
                    wt,
                    wp.cw_mul(child_tau, kt),
                    depth + 1,
                    RAY_TRANSMISSION,
                    node,
                )
            if go_r:
                rdir = wp.normalize(reflect(rd, n))
                sp = push(
                    st,
                    row,
                    sp,
                    offset_origin(h.p, nf, rdir),
                    rdir,
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
    return color, counts


@wp.func
def trace_sample(scene: SceneData, x: int, y: int, s: int, st: Stack, row: int, record: int, rec: TreeRecord):
    """Sample s of pixel (x, y): its film position, camera ray and ray tree."""
    rng = rng_start(scene.seed, y * scene.width + x, s)
    u1 = wp.randf(rng)
    u2 = wp.randf(rng)
    uv = box_filter_offset(film_offset(scene.sampler, s, scene.spp, u1, u2), scene.filter_radius)
    o, d = camera_ray(scene.camera, float(x) + uv[0], float(y) + uv[1], scene.width, scene.height)
    return trace(scene, o, d, st, row, record, rec)


@wp.kernel
def render_rows(
    scene: SceneData,
    y0: int,
    s0: int,
    s1: int,
    st: Stack,
    rec: TreeRecord,
    accum: wp.array2d(dtype=wp.vec3),
    counts: wp.array2d(dtype=wp.vec4i),
):
    """Add samples s0..s1-1 of each pixel of rows y0.. to the running sums (one thread per pixel)."""
    row = wp.tid()
    x = row % scene.width
    y = y0 + row / scene.width
    if y >= scene.height:
        return
    acc = accum[y, x]
    cnt = counts[y, x]
    for s in range(s0, s1):
        c, n = trace_sample(scene, x, y, s, st, row, 0, rec)
        acc = acc + c
        cnt = cnt + n
    accum[y, x] = acc
    counts[y, x] = cnt


@wp.kernel
def trace_one(scene: SceneData, x: int, y: int, s: int, st: Stack, rec: TreeRecord, out: wp.array(dtype=wp.vec3)):
    """One pixel sample with its ray tree recorded."""
    c, n = trace_sample(scene, x, y, s, st, 0, 1, rec)
    out[0] = c
