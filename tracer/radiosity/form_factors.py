"""The radiosity solver's kernels: one shot's rays (ray-cast form factors, Malley's method), and the
direct irradiance of point, spot and directional lights at the patches.

A shot casts `rays` rays from points spread uniformly over the shooter (stratified), in
cosine-weighted directions about its normal, to the first surface each meets, found with the scene's
own geometry (`closest_hit`) and mapped to the patch there (`patch_at`). The rays run in parallel (one
band of rays per thread); every ray writes the patch it reached, and the patches count their rays
(solver.py), so the sums never depend on the threads.
"""

import warp as wp

from tracer.kernels.geometry import closest_hit
from tracer.kernels.kinds import RAY_OFFSET, SHOOT_PATCH, T_FAR
from tracer.kernels.lights import light_at, surface_point
from tracer.kernels.sampling import rng_start, sample_cosine_hemisphere, to_world
from tracer.kernels.structs import PatchIndex, SceneData
from tracer.radiosity.lookup import patch_at

TARGET_ESCAPED = wp.constant(-1)  # a ray that left the scene (or reached a surface that has no patches)
TARGET_LIGHT = wp.constant(-2)  # a ray that ended on an area light (black: absorbed)


@wp.kernel
def shoot(
    scene: SceneData,
    ix: PatchIndex,
    shooter: int,  # SHOOT_PATCH: a patch side (corner, e1, e2, triangle flag; on a sphere); SHOOT_LIGHT
    corner: wp.vec3,
    e1: wp.vec3,
    e2: wp.vec3,
    tri: int,
    sphere_center: wp.vec3,
    sphere_radius: float,  # > 0: the patch stands for the piece of this sphere above it
    light_index: int,
    seed: int,
    step: int,
    first: int,  # this launch casts rays first, first + 1, ... of the shot's n_rays
    n_rays: int,
    target: wp.array(dtype=wp.int32),
):
    """One ray of a shot per thread: from a point of the shooter, in a cosine-weighted direction about
    its normal, to the first surface; writes the patch side it reached (or TARGET_*) at its index."""
    r = first + wp.tid()
    rng = rng_start(seed, step, r)
    m = int(wp.floor(wp.sqrt(float(n_rays))))
    u1 = wp.randf(rng)
    u2 = wp.randf(rng)
    if r < m * m:  # stratified positions on the shooter
        u1 = (float(r % m) + u1) / float(m)
        u2 = (float(r / m) + u2) / float(m)
    p = wp.vec3(0.0)
    n = wp.vec3(0.0, 1.0, 0.0)
    if shooter == SHOOT_PATCH:
        a = u1
        b = u2
        if tri != 0 and a + b > 1.0:
            a = 1.0 - a
            b = 1.0 - b
        p = corner + a * e1 + b * e2
        n = wp.normalize(wp.cross(e1, e2))
        if sphere_radius > 0.0:  # the point of the sphere above the facet's point, and the sphere's normal
            radial = wp.normalize(p - sphere_center)
            p = sphere_center + sphere_radius * radial
            n = wp.where(wp.dot(radial, n) < 0.0, -radial, radial)
    else:
        p, n = surface_point(scene.lights[light_index], u1, u2)
    d = to_world(sample_cosine_hemisphere(wp.randf(rng), wp.randf(rng)), n)
    h = closest_hit(scene, p + RAY_OFFSET * n, d, T_FAR, 0.0)
    out = int(TARGET_ESCAPED)
    if h.hit != 0:
        if h.obj < 0:
            out = TARGET_LIGHT
        else:
            nf = wp.where(wp.dot(d, h.ng) < 0.0, h.ng, -h.ng)  # the true surface's side the ray arrives on
            k, face, bu, bv = patch_at(ix, h.po, nf, h.obj)
            out = k
    target[r] = out


@wp.kernel
def direct(
    scene: SceneData,
    points: wp.array(dtype=wp.vec3),
    normals: wp.array(dtype=wp.vec3),
    light_index: int,
    first: int,
    received: wp.array(dtype=wp.vec3),
):
    """Irradiance of a point, spot or directional light at each patch side's centre (one shadow ray)."""
    i = first + wp.tid()
    light = scene.lights[light_index]
    p = points[i]
    n = normals[i]
    l, dist, e, reaches = light_at(light, p)
    cos = wp.dot(n, l)
    if reaches != 0 and cos > 0.0:
        o = p + RAY_OFFSET * n
        h = closest_hit(scene, o, l, dist, 0.0)
        if h.hit == 0:
            received[i] = e * cos  # W/m^2; times the area outside
