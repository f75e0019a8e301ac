"""What every integrator does at a hit: the surface's normals and material, spawn offsets, lobes."""

import warp as wp

from tracer.compile import MaterialData, SceneData
from tracer.geometry import Hit
from tracer.kinds import RAY_OFFSET
from tracer.materials import bump_normal, diffuse_color
from tracer.sampling import sample_cos_lobe, to_world


@wp.struct
class Surface:
    """A hit made ready for shading."""

    m: MaterialData
    front: int  # 1 when the ray arrived on the side the geometric normal points to
    nf: wp.vec3  # geometric normal turned towards the incoming ray (spawn offsets)
    n: wp.vec3  # shading normal (smooth, bumped) turned towards the incoming ray
    kd: wp.vec3  # diffuse colour after texturing
    ka: wp.vec3  # ambient coefficient (= kd unless the material sets ka)
    emission: wp.vec3  # emitted radiance towards the ray (front face only)


@wp.struct
class SampleOut:
    """One pixel sample: its radiance, its rays by RAY_* kind, and its first hit (for the AOVs)."""

    color: wp.vec3
    counts: wp.vec4i
    depth: float  # distance to the eye ray's hit; 0 when it left the scene
    normal: wp.vec3  # shading normal there (zero on a miss)
    albedo: wp.vec3  # kd there (zero on a miss)


@wp.func
def surface_at(scene: SceneData, h: Hit, rd: wp.vec3) -> Surface:
    s = Surface()
    s.m = scene.materials[h.mat]
    front = wp.dot(rd, h.ng) < 0.0
    s.front = wp.where(front, 1, 0)
    s.nf = wp.where(front, h.ng, -h.ng)
    s.n = bump_normal(scene, s.m, h.po, wp.where(front, h.ns, -h.ns), h.uv, h.dpdu, h.dpdv)
    s.kd = diffuse_color(scene, s.m, h.po, h.ng, h.uv)
    s.ka = wp.where(s.m.ka_is_kd != 0, s.kd, s.m.ka)
    s.emission = wp.where(front, s.m.emission, wp.vec3(0.0))
    return s


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
def glossy_direction(ideal: wp.vec3, gloss: float, u1: float, u2: float) -> wp.vec3:
    """The ideal mirror or refraction direction itself, or (gloss = m > 0) a direction drawn from
    the cos^m lobe around it (glossy reflection, translucency)."""
    if gloss <= 0.0:
        return ideal
    return wp.normalize(to_world(sample_cos_lobe(u1, u2, gloss), ideal))
