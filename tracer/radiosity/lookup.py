"""The radiosity solution at a hit: the @wp.func the integrators call (`radiosity_ambient`, through
`radiosity_at` and `patch_at`; the solver's rays find the patches they reach with `patch_at` too).

Units: radiosity B is exitance, W/m^2; the radiance a diffuse patch sends out is B / pi.
"""

import warp as wp

from tracer.kernels.geometry import PI
from tracer.kernels.kinds import PATCHES_DISK, PATCHES_FLAT, PATCHES_NONE, PATCHES_SPHERE, RAD_FLAT, RAD_TWO_PASS
from tracer.kernels.structs import PatchIndex, RadiosityData

SPHERE_REACH = wp.constant(1.001)  # a ray from a sphere's centre to its facets (inscribed) goes this far, in radii


@wp.func(inline=True)
def patch_at(ix: PatchIndex, p: wp.vec3, nf: wp.vec3, obj: int):
    """The radiosity patch side under the point p of object obj (at time 0), on the side nf points to:
    (patch side k, its triangle in ix.mesh, barycentrics u, v there), or k = -1 off the patches (an area
    light, a plane beyond the meshed part, an object the solve does not see).

    Flat surfaces lie on their facets: the nearest facet. A sphere's facets are inscribed in it: the
    facet that the ray from the centre through p crosses. A disk's rim bulges past its polygon of
    facets: the point is first pulled radially inside the polygon."""
    face = int(-1)
    u = float(0.0)
    v = float(0.0)
    kind = PATCHES_NONE
    if obj >= 0:
        kind = ix.obj_kind[obj]
    if kind == PATCHES_SPHERE:
        c = ix.obj_center[obj]
        qr = wp.mesh_query_ray(ix.mesh, c, wp.normalize(p - c), ix.obj_radius[obj] * SPHERE_REACH)
        if qr.result:
            face = qr.face
            u = qr.u
            v = qr.v
    elif kind == PATCHES_FLAT or kind == PATCHES_DISK:
        x = p
        if kind == PATCHES_DISK:
            c = ix.obj_center[obj]
            r = wp.length(p - c)
            if r > ix.obj_radius[obj]:
                x = c + (p - c) * (ix.obj_radius[obj] / r)
        q = wp.mesh_query_point_no_sign(ix.mesh, x, ix.max_dist)
        if q.result:
            face = q.face
            u = q.u
            v = q.v
    if face < 0:
        return -1, -1, u, v
    if ix.tri_obj[face] != obj:  # a different surface just as close (a light on a ceiling)
        return -1, -1, u, v
    k = ix.tri_patch[face]
    if wp.dot(wp.mesh_eval_face_normal(ix.mesh, face), nf) < 0.0:  # the back side
        k = k + ix.n
    return k, face, u, v


@wp.func(inline=True)
def radiosity_at(rad: RadiosityData, p: wp.vec3, nf: wp.vec3, obj: int):
    """The radiosity solution at a hit at p on object obj, seen from the side nf points to:
    (1, B, the interreflected part of B, rho), or (0, ...) off the patches (see `patch_at`).
    B and its interreflected part are the patch's own values in the flat display, else
    interpolated from the patch's corners (smooth display, two-pass shading)."""
    zero = wp.vec3(0.0)
    k, face, u, v = patch_at(rad.index, p, nf, obj)
    if k < 0:
        return 0, zero, zero, zero
    b = rad.radiosity[k]
    ind = rad.indirect[k]
    if rad.mode != RAD_FLAT:  # smooth display, and the two-pass interreflection: interpolated at the corners
        c = 3 * face
        if k >= rad.index.n:  # the back side's corners follow the front sides'
            c = c + 3 * rad.index.tri_patch.shape[0]
        w = 1.0 - u - v
        b = u * rad.corners[c] + v * rad.corners[c + 1] + w * rad.corners[c + 2]
        ind = u * rad.corners_ind[c] + v * rad.corners_ind[c + 1] + w * rad.corners_ind[c + 2]
    return 1, b, ind, rad.rho[k]


@wp.func
def safe_div(a: wp.vec3, b: wp.vec3) -> wp.vec3:
    return wp.vec3(
        wp.where(b[0] > 0.0, a[0] / b[0], 0.0),
        wp.where(b[1] > 0.0, a[1] / b[1], 0.0),
        wp.where(b[2] > 0.0, a[2] / b[2], 0.0),
    )


@wp.func(inline=True)
def radiosity_ambient(rad: RadiosityData, kd: wp.vec3, p: wp.vec3, nf: wp.vec3, obj: int):
    """What the solution puts in place of the ambient term at a hit (kd the diffuse colour there):
    (radiance, 1 if it is the patch's own radiance and replaces the whole local term).

    Two-pass display: kd / pi times the interreflected irradiance (the interreflected B over the patch's
    rho), so the ray tree adds the direct light and the mirrors. Flat and smooth displays: B / pi, the
    radiance of the patch itself. Off the patches: no ambient term."""
    found, b, ind, rho = radiosity_at(rad, p, nf, obj)
    if found == 0:
        return wp.vec3(0.0), 0
    if rad.mode == RAD_TWO_PASS:
        return wp.cw_mul(kd, safe_div(ind, rho)) / PI, 0
    return b / PI, 1
