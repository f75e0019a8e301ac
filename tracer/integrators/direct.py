"""Direct lighting at a shading point: shadow rays towards the lights, shaded by the Phong BRDF.

A point, spot or directional light gets one shadow ray where it can contribute (N.L > 0, inside a
spot's cone). An area light gets `light_samples` rays towards stratified points of its surface,
each carrying an equal share of its E (tracer/kernels/lights.py). A shadow ray starts at hit + 1e-4 N, N the
geometric normal turned to the light's side, and is blocked by any surface before the light (an
area light's own surface does not shadow itself). Each unblocked ray adds E cos(theta) f, split
into its diffuse and specular parts so the ray tree can show them.

Both integrators call `direct_light`; they differ only in where the points on area lights come
from: `whitted` jitters strata with its random state (distribution ray tracing, Cook et al. 1984),
`path` takes Roberts' R2 points of the pixel's successive samples and weights each by multiple
importance sampling against its BSDF sampling (Veach & Guibas 1995).
"""

import warp as wp

from tracer.integrators.common import Surface, offset_origin
from tracer.integrators.record import TreeRecord, record_shadow
from tracer.kernels.geometry import Hit, closest_hit, intersect_shape, occluded
from tracer.kernels.kinds import T_FAR
from tracer.kernels.lights import is_area_light, light_at, sample_area_light
from tracer.kernels.materials import phong_terms
from tracer.kernels.sampling import phong_lobes_pdf, power_heuristic, sample_2d, stratum
from tracer.kernels.structs import LightData, SceneData

STRATIFIED = wp.constant(-1)  # direct_light's `dim` for jittered strata drawn from its rng (whitted; no MIS)


@wp.func(inline=True)
def light_sample(light: LightData, p: wp.vec3, u: wp.vec2, n_rays: int):
    """One shadow-ray sample of a light seen from p, u picking the point of an area light: (unit
    direction, distance, E of this ray (an area light's share: 1 / n_rays of it), solid-angle pdf of
    the direction (area lights; 0 otherwise), 1 if the light reaches p)."""
    if is_area_light(light):
        l, dist, e, pdf, reaches = sample_area_light(light, p, u[0], u[1])
        return l, dist, e / float(n_rays), pdf, reaches
    l, dist, e, reaches = light_at(light, p)
    return l, dist, e, 0.0, reaches


@wp.func(inline=True)
def shadow_reach(scene: SceneData, light: LightData, so: wp.vec3, l: wp.vec3, dist: float) -> float:
    """How far a shadow ray from so along l may go: to the light at distance `dist`, or for an area
    light to where the ray meets the light's own surface (which does not shadow itself)."""
    if light.shape >= 0:
        t = intersect_shape(scene.shapes[light.shape], so, l, T_FAR)
        if t > 0.0:
            return t
    return dist


@wp.func(inline=True)
def shadow_test(
    scene: SceneData, so: wp.vec3, l: wp.vec3, t_max: float, time: float, record: int, light_shape: int
) -> Hit:
    """The shadow ray's occluder (hit = 1) or none. Rendering asks only whether there is one (never
    testing the light's own shape, which t_max reaches); the ray tree (record = 1) also wants the nearest
    one, which the same test finds."""
    if record != 0:
        return closest_hit(scene, so, l, t_max, time)
    h = Hit()
    h.hit = occluded(scene, so, l, t_max, time, light_shape)
    return h


@wp.func(inline=True)
def direct_light(
    scene: SceneData,
    s: Surface,
    v: wp.vec3,
    time: float,
    lights: int,
    rng: wp.uint32,
    key: wp.uint32,
    dim: int,
    sample: int,
    pd: float,
    ps: float,
    rdir: wp.vec3,
    record: int,
    rec: TreeRecord,
    node: int,
    depth: int,
    w: wp.vec3,
):
    """Light from scene.lights[0 .. lights-1] reflected at s towards v (unit, to the viewer), at `time`:
    (diffuse, specular, shadow rays traced, rng after its draws).

    Points on area lights: dim = STRATIFIED (whitted): jittered strata, two draws of `rng` per ray. dim >= 0
    (path): the R2 points of the pixel's samples (`key`, `sample`; light li at dimension dim + li),
    each weighted by the power heuristic against choosing the diffuse lobe (probability pd) or the
    Phong lobe about rdir (ps) and sampling it. The ray tree (record, rec): each shadow ray a child
    of `node`, at its `depth`, with its weight w."""
    diffuse = wp.vec3(0.0)
    specular = wp.vec3(0.0)
    rays = int(0)
    state = wp.uint32(rng)
    for li in range(lights):
        light = scene.lights[li]
        area = is_area_light(light)
        n_rays = wp.where(area, scene.light_samples, 1)
        for k in range(n_rays):
            u = wp.vec2(0.0)
            if dim >= 0:  # the k-th of the pixel's (sample x light_samples) points on this light, evenly spread
                u = sample_2d(key, dim + li, sample * n_rays + k)
            elif area:
                u = stratum(k, n_rays, wp.randf(state), wp.randf(state))
            l, dist, e, pl, reaches = light_sample(light, s.p, u, n_rays)
            mis = float(1.0)
            if area and dim >= 0:
                mis = power_heuristic(float(n_rays), pl, 1.0, phong_lobes_pdf(pd, ps, s.m.shininess, s.n, rdir, l))
            if reaches != 0 and wp.dot(s.n, l) > 0.0:
                so = offset_origin(s.p, s.nf, l)
                rays += 1
                occluder = shadow_test(scene, so, l, shadow_reach(scene, light, so, l, dist), time, record, light.shape)
                dterm, sterm = phong_terms(s.kd, s.m.ks, s.m.shininess, s.n, l, v)
                dterm = wp.cw_mul(e, dterm) * mis
                sterm = wp.cw_mul(e, sterm) * mis
                if occluder.hit == 0:
                    diffuse += dterm
                    specular += sterm
                record_shadow(rec, node, depth, so, l, w, time, li, occluder, dterm + sterm)
    return diffuse, specular, rays, state
