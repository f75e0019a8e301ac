"""Ray-shape intersections and the closest hit (Warp @wp.func helpers).

Analytic shapes are tested exactly, one after another; all triangles sit in one ``wp.Mesh``
whose BVH answers ``wp.mesh_query_ray``. Warp's barycentrics: p = u v0 + v v1 + (1 - u - v) v2.
A ray hits a surface at distance t only for 0 < t < t_max; spawned rays are offset along the
normal by the caller (docs/scene-format.md, "Where spawned rays start"), so no epsilon on t is needed here.
"""

import warp as wp

from tracer.kernels.kinds import BUMP_NONE, SHAPE_BOX, SHAPE_DISK, SHAPE_PLANE, SHAPE_QUAD, SHAPE_SPHERE, TEX_NONE
from tracer.kernels.structs import FACE_SMOOTH, FACE_UV, SceneData, ShapeData

PI = wp.constant(3.14159265358979323846)


@wp.struct
class Hit:
    hit: int  # 1 when the ray hit something before t_max
    t: float  # distance along the (unit) ray direction
    p: wp.vec3  # hit point
    ng: wp.vec3  # geometric normal as the shape defines it (not turned towards the ray)
    ns: wp.vec3  # interpolated normal (smooth meshes), same side as ng; = ng otherwise
    obj: int  # object index in the scene (-1 - k for area light k)
    mat: int  # material index
    light: int  # area light index, or -1
    po: wp.vec3  # the hit point where the object is at time 0 (textures move with the object)
    uv: wp.vec2  # surface coordinates for image textures and bump maps
    dpdu: wp.vec3  # surface tangents along u and v (for bump maps)
    dpdv: wp.vec3


@wp.func
def intersect_sphere(o: wp.vec3, d: wp.vec3, center: wp.vec3, radius: float, t_max: float) -> float:
    """Nearest t in (0, t_max) of |o + t d - center| = radius for unit d, or -1."""
    oc = o - center
    b = wp.dot(oc, d)
    c = wp.dot(oc, oc) - radius * radius
    disc = b * b - c
    if disc < 0.0:
        return -1.0
    s = wp.sqrt(disc)
    t = -b - s
    if t <= 0.0:
        t = -b + s
    if t <= 0.0 or t >= t_max:
        return -1.0
    return t


@wp.func
def intersect_plane(o: wp.vec3, d: wp.vec3, point: wp.vec3, normal: wp.vec3, t_max: float) -> float:
    denom = wp.dot(d, normal)
    if wp.abs(denom) < 1.0e-12:
        return -1.0
    t = wp.dot(point - o, normal) / denom
    if t <= 0.0 or t >= t_max:
        return -1.0
    return t


@wp.func
def quad_coords(p: wp.vec3, corner: wp.vec3, e1: wp.vec3, e2: wp.vec3) -> wp.vec2:
    """(a, b) with p = corner + a e1 + b e2, for p in the quad's plane."""
    n = wp.cross(e1, e2)
    w = n / wp.dot(n, n)
    q = p - corner
    return wp.vec2(wp.dot(w, wp.cross(q, e2)), wp.dot(w, wp.cross(e1, q)))


@wp.func
def intersect_parallelogram(
    o: wp.vec3, d: wp.vec3, corner: wp.vec3, n: wp.vec3, wa: wp.vec3, wb: wp.vec3, t_max: float
) -> float:
    """corner + a e1 + b e2, a, b in [0, 1]; n the unit normal along e1 x e2, and with m = e1 x e2,
    wa = e2 x m / |m|^2 and wb = m x e1 / |m|^2 precomputed, so that a = wa . (p - corner) and
    b = wb . (p - corner) for p in the plane."""
    t = wp.dot(corner - o, n) / wp.dot(d, n)
    if not (t > 0.0 and t < t_max):  # also false for the NaN/inf of a ray parallel to the plane
        return -1.0
    q = o + t * d - corner
    a = wp.dot(wa, q)
    if a < 0.0 or a > 1.0:
        return -1.0
    b = wp.dot(wb, q)
    if b < 0.0 or b > 1.0:
        return -1.0
    return t


@wp.func
def intersect_disk(o: wp.vec3, d: wp.vec3, center: wp.vec3, normal: wp.vec3, radius: float, t_max: float) -> float:
    t = intersect_plane(o, d, center, normal, t_max)
    if t < 0.0:
        return -1.0
    q = o + t * d - center
    if wp.dot(q, q) > radius * radius:
        return -1.0
    return t


@wp.func(inline=True)
def intersect_box(
    o: wp.vec3, d: wp.vec3, xf: wp.mat33, offset: wp.vec3, lo: wp.vec3, hi: wp.vec3, t_max: float
) -> float:
    """Slab test in the box's coordinates (local = xf world + offset, an affine map, so t is the
    world t): the entry distance, or the exit distance from inside, or -1."""
    lo_o = xf * o + offset
    lo_d = xf * d
    t_near = float(-1.0e30)
    t_far = float(1.0e30)
    for k in range(3):
        inv = 1.0 / lo_d[k]
        ta = (lo[k] - lo_o[k]) * inv
        tb = (hi[k] - lo_o[k]) * inv
        t0 = wp.where(ta < tb, ta, tb)
        t1 = wp.where(ta < tb, tb, ta)
        t_near = wp.where(t0 > t_near, t0, t_near)
        t_far = wp.where(t1 < t_far, t1, t_far)
    if not (t_near <= t_far):
        return -1.0
    t = wp.where(t_near > 0.0, t_near, t_far)
    if not (t > 0.0 and t < t_max):
        return -1.0
    return t


@wp.func(inline=True)
def intersect_shape(s: ShapeData, o: wp.vec3, d: wp.vec3, t_max: float) -> float:
    """One dispatch over SHAPE_* kinds: t of the hit in (0, t_max), or -1 (shape at time 0)."""
    if s.kind == SHAPE_SPHERE:
        return intersect_sphere(o, d, s.p0, s.radius, t_max)
    if s.kind == SHAPE_PLANE:
        return intersect_plane(o, d, s.p0, s.p1, t_max)
    if s.kind == SHAPE_QUAD:
        return intersect_parallelogram(o, d, s.p0, s.n, s.w, s.w2, t_max)
    if s.kind == SHAPE_DISK:
        return intersect_disk(o, d, s.p0, s.p1, s.radius, t_max)
    if s.kind == SHAPE_BOX:
        return intersect_box(o, d, s.xf, s.p2, s.p0, s.p1, t_max)
    return -1.0


@wp.func
def basis(n: wp.vec3):
    """Two unit tangents (t, b) with (t, b, n) right-handed (Duff et al. 2017)."""
    sign = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]), wp.vec3(b, sign + n[1] * n[1] * a, -n[1])


@wp.func(inline=True)
def shape_surface(s: ShapeData, p: wp.vec3, h: Hit, uv: int) -> Hit:
    """Fill the normal of a hit point p on analytic shape s, and with uv = 1 its uv and tangents (which
    only textures and bump maps read: without them the hit's uv and tangents stay zero)."""
    r = h
    if s.kind == SHAPE_SPHERE:
        n = (p - s.p0) / s.radius
        r.ng = n
        if uv == 0:
            r.ns = r.ng
            return r
        phi = wp.atan2(-n[2], n[0]) + PI
        theta = wp.acos(wp.clamp(-n[1], -1.0, 1.0))
        r.uv = wp.vec2(phi / (2.0 * PI), theta / PI)
        r.dpdu = wp.vec3(n[2], 0.0, -n[0]) * (2.0 * PI * s.radius)
        if wp.length(r.dpdu) < 1.0e-6:
            tu, tv = basis(n)
            r.dpdu = tu
        r.dpdv = wp.normalize(wp.cross(n, r.dpdu)) * (PI * s.radius)
    elif s.kind == SHAPE_BOX:
        # the face the point lies on: the nearest of the six, relative to the box's size
        q = s.xf * p + s.p2
        size = s.p1 - s.p0
        best = float(1.0e30)
        axis = int(0)
        side = float(1.0)
        for k in range(3):
            dl = wp.abs(q[k] - s.p0[k]) / size[k]
            dh = wp.abs(s.p1[k] - q[k]) / size[k]
            if dl < best:
                best = dl
                axis = k
                side = -1.0
            if dh < best:
                best = dh
                axis = k
                side = 1.0
        nl = wp.vec3(0.0)
        nl[axis] = side
        r.ng = wp.normalize(wp.transpose(s.xf) * nl)  # normals transform by the inverse transpose
        if uv == 0:
            r.ns = r.ng
            return r
        a1 = (axis + 1) % 3
        a2 = (axis + 2) % 3
        r.uv = wp.vec2((q[a1] - s.p0[a1]) / size[a1], (q[a2] - s.p0[a2]) / size[a2])
        fwd = wp.inverse(s.xf)
        e1 = wp.vec3(0.0)
        e1[a1] = size[a1]
        e2 = wp.vec3(0.0)
        e2[a2] = size[a2]
        r.dpdu = fwd * e1
        r.dpdv = fwd * e2
    elif s.kind == SHAPE_QUAD:
        r.ng = s.n
        if uv != 0:
            r.uv = quad_coords(p, s.p0, s.p1, s.p2)
            r.dpdu = s.p1
            r.dpdv = s.p2
    else:  # plane and disk: planar coordinates in world units (disk: 0..1 across its diameter)
        r.ng = s.p1
        if uv == 0:
            r.ns = r.ng
            return r
        t, b = basis(s.p1)
        q = p - s.p0
        if s.kind == SHAPE_DISK:
            r.uv = wp.vec2(0.5 + wp.dot(q, t) / (2.0 * s.radius), 0.5 + wp.dot(q, b) / (2.0 * s.radius))
            r.dpdu = t * (2.0 * s.radius)
            r.dpdv = b * (2.0 * s.radius)
        else:
            r.uv = wp.vec2(wp.dot(q, t), wp.dot(q, b))
            r.dpdu = t
            r.dpdv = b
    r.ns = r.ng
    return r


@wp.func(inline=True)
def closest_hit(scene: SceneData, o: wp.vec3, d: wp.vec3, t_max: float, time: float) -> Hit:
    """The nearest surface along o + t d, 0 < t < t_max (unit d), with objects where they are at `time`.

    A moving object is at p + velocity time, so it is tested against the ray moved the other way.
    """
    h = Hit()
    h.hit = 0
    h.t = t_max
    h.light = -1
    best = int(-1)
    for i in range(scene.num_quads):  # the quads come first: no dispatch over kinds
        s = scene.shapes[i]
        oi = o
        if scene.shapes_move != 0:  # a static scene skips the motion's arithmetic
            oi = o - s.velocity * time
        t = intersect_parallelogram(oi, d, s.p0, s.n, s.w, s.w2, h.t)
        if t > 0.0:
            h.t = t
            best = i
    for i in range(scene.num_quads, scene.num_shapes):
        s = scene.shapes[i]
        oi = o
        if scene.shapes_move != 0:
            oi = o - s.velocity * time
        t = intersect_shape(s, oi, d, h.t)
        if t > 0.0:
            h.t = t
            best = i
    face = int(-1)
    bu = float(0.0)
    bv = float(0.0)
    group = int(0)
    for g in range(scene.num_meshes):
        q = wp.mesh_query_ray(scene.meshes[g], o - scene.mesh_vel[g] * time, d, h.t)
        if q.result and q.t > 0.0 and q.t < h.t:
            h.t = q.t
            face = scene.mesh_face0[g] + q.face
            bu = q.u
            bv = q.v
            group = g
            best = -1
    if face >= 0:
        h.hit = 1
        h.p = o + h.t * d
        h.obj = scene.face_obj[face]
        h.mat = scene.face_mat[face]
        h = triangle_surface(scene, face, bu, bv, h, needs_uv(scene, h.mat))
        h.po = h.p - scene.mesh_vel[group] * time
    elif best >= 0:
        h.hit = 1
        s = scene.shapes[best]
        h.p = o + h.t * d
        h.po = h.p - s.velocity * time
        h.obj = s.obj
        h.mat = s.mat
        h.light = s.light
        h = shape_surface(s, h.po, h, needs_uv(scene, s.mat))
    return h


@wp.func(inline=True)
def occluded(scene: SceneData, o: wp.vec3, d: wp.vec3, t_max: float, time: float, skip: int) -> int:
    """1 if any surface lies along o + t d with 0 < t < t_max (shadow rays: the first one found will do).
    The same test as closest_hit's, so closest_hit(...).hit gives the same answer. Shape `skip` (or -1)
    is left out: a shadow ray's own light, whose surface t_max reaches (direct.shadow_reach), which the
    test t < t_max would reject anyway."""
    for i in range(scene.num_quads):
        if i == skip:
            continue
        s = scene.shapes[i]
        oi = o
        if scene.shapes_move != 0:
            oi = o - s.velocity * time
        if intersect_parallelogram(oi, d, s.p0, s.n, s.w, s.w2, t_max) > 0.0:
            return 1
    for i in range(scene.num_quads, scene.num_shapes):
        if i == skip:
            continue
        s = scene.shapes[i]
        oi = o
        if scene.shapes_move != 0:
            oi = o - s.velocity * time
        if intersect_shape(s, oi, d, t_max) > 0.0:
            return 1
    for g in range(scene.num_meshes):
        if wp.mesh_query_ray_anyhit(scene.meshes[g], o - scene.mesh_vel[g] * time, d, t_max):
            return 1
    return 0


@wp.func(inline=True)
def needs_uv(scene: SceneData, mat: int) -> int:
    """1 when material `mat` reads a hit's uv or tangents (an image texture, a bump map), else 0."""
    m = scene.materials[mat]
    return wp.where(m.tex != TEX_NONE or m.bump != BUMP_NONE, 1, 0)


@wp.func(inline=True)
def triangle_surface(scene: SceneData, face: int, bu: float, bv: float, h: Hit, uv: int) -> Hit:
    """Normals of a hit on mesh face `face` at Warp barycentrics (bu, bv), and with uv = 1 its uv and
    tangents."""
    i0 = scene.mesh_indices[3 * face + 0]
    i1 = scene.mesh_indices[3 * face + 1]
    i2 = scene.mesh_indices[3 * face + 2]
    v0 = scene.mesh_points[i0]
    v1 = scene.mesh_points[i1]
    v2 = scene.mesh_points[i2]
    h.ng = wp.normalize(wp.cross(v1 - v0, v2 - v0))
    bw = 1.0 - bu - bv
    flags = scene.face_flags[face]
    h.ns = h.ng
    if (flags & FACE_SMOOTH) != 0:
        ns = bu * scene.mesh_normals[i0] + bv * scene.mesh_normals[i1] + bw * scene.mesh_normals[i2]
        if wp.length(ns) > 1.0e-8:
            ns = wp.normalize(ns)
            h.ns = wp.where(wp.dot(ns, h.ng) < 0.0, -ns, ns)
    if uv == 0:
        return h
    uv0 = wp.vec2(0.0, 0.0)
    uv1 = wp.vec2(1.0, 0.0)
    uv2 = wp.vec2(0.0, 1.0)
    if (flags & FACE_UV) != 0:
        uv0 = scene.mesh_uvs[i0]
        uv1 = scene.mesh_uvs[i1]
        uv2 = scene.mesh_uvs[i2]
    h.uv = bu * uv0 + bv * uv1 + bw * uv2
    # tangents from the uv parameterisation: dp = dpdu du + dpdv dv over the triangle's edges
    du1 = uv1 - uv0
    du2 = uv2 - uv0
    dp1 = v1 - v0
    dp2 = v2 - v0
    det = du1[0] * du2[1] - du1[1] * du2[0]
    if wp.abs(det) > 1.0e-12:
        h.dpdu = (du2[1] * dp1 - du1[1] * dp2) / det
        h.dpdv = (du1[0] * dp2 - du2[0] * dp1) / det
    else:
        tu, tv = basis(h.ng)
        h.dpdu = tu
        h.dpdv = tv
    return h
