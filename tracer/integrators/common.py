"""What every integrator shares: the interface's types (SampleOut, Stack), the surface at a hit made
ready for shading, spawn offsets, the reflection and transmission weights, fog and the background.

Every @wp.func here that takes a struct is inlined: Warp passes structs by value (tracer/kernels/structs.py).
"""

import warp as wp

from tracer.kernels.geometry import Hit
from tracer.kernels.kinds import BUMP_NONE, RAY_OFFSET, TEX_NONE
from tracer.kernels.materials import bump_normal, diffuse_color, fresnel_dielectric, refract
from tracer.kernels.sampling import sample_cos_lobe, to_world
from tracer.kernels.structs import MaterialData, SceneData, struct


@struct
class SampleOut:
    """One pixel sample: its radiance, its rays by RAY_* kind, and its first hit (for the AOVs)."""

    color: wp.vec3  # radiance along the eye ray
    counts: wp.vec4i  # rays traced, by RAY_* kind
    depth: float  # distance to the eye ray's hit; 0 when it left the scene
    normal: wp.vec3  # shading normal there (zero on a miss)
    albedo: wp.vec3  # kd there (zero on a miss)


@struct
class Stack:
    """Per-thread scratch of the integrators that keep pending rays (whitted's ray tree): row = thread,
    column = stack slot. Every integrator's `trace` receives it; the others leave it alone."""

    o: wp.array2d(dtype=wp.vec3)  # origin
    d: wp.array2d(dtype=wp.vec3)  # unit direction
    k: wp.array2d(dtype=wp.vec3)  # the ray's own K (kr or kt, with Fresnel)
    w: wp.array2d(dtype=wp.vec3)  # product of K's from the eye to this ray
    tau: wp.array2d(dtype=wp.vec3)  # w times the fog transmittance of its ancestors
    i: wp.array2d(dtype=wp.vec3i)  # depth, kind, parent node


@struct
class Surface:
    """A hit made ready for shading."""

    m: MaterialData
    p: wp.vec3  # the hit point
    front: int  # 1 when the ray arrived on the side the geometric normal points to
    nf: wp.vec3  # geometric normal turned towards the incoming ray (spawn offsets)
    n: wp.vec3  # shading normal (smooth, bumped) turned towards the incoming ray
    kd: wp.vec3  # diffuse colour after texturing
    ka: wp.vec3  # ambient coefficient (= kd unless the material sets ka)
    emission: wp.vec3  # emitted radiance towards the ray (front face only)


@wp.func
def no_sample() -> SampleOut:
    """A sample that has seen nothing yet: black, no rays, no hit."""
    out = SampleOut()
    out.color = wp.vec3(0.0)
    out.counts = wp.vec4i(0)
    out.depth = 0.0
    out.normal = wp.vec3(0.0)
    out.albedo = wp.vec3(0.0)
    return out


@wp.func(inline=True)
def surface_at(scene: SceneData, h: Hit, rd: wp.vec3) -> Surface:
    """The material, normals and colours at hit h of a ray travelling along rd."""
    s = Surface()
    s.m = scene.materials[h.mat]
    s.p = h.p
    front = wp.dot(rd, h.ng) < 0.0
    s.front = wp.where(front, 1, 0)
    s.nf = wp.where(front, h.ng, -h.ng)
    s.n = wp.where(front, h.ns, -h.ns)
    if s.m.bump != BUMP_NONE:
        s.n = bump_normal(scene, s.m, h.po, s.n, h.uv, h.dpdu, h.dpdv)
    s.kd = s.m.kd
    if s.m.tex != TEX_NONE:
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


@wp.func(inline=True)
def scatter_weights(m: MaterialData, rd: wp.vec3, n: wp.vec3, front: int):
    """The weights of the reflection and transmission rays at a hit, and the refracted direction:
    (kr, kt, transmitted direction, 1 under total internal reflection). With `fresnel` the weights
    are scaled by R and 1 - R; under TIR the transmission ray's weight goes to the reflection ray
    (kt without Fresnel, 0 with it since R = 1). docs/scene-format.md, "Reflection and transmission rays"."""
    kr = m.kr
    kt = m.kt
    tdir = wp.vec3(0.0)
    tir = int(0)
    eta = wp.where(front != 0, 1.0 / m.ior, m.ior)  # n_incident / n_transmitted
    if kt[0] > 0.0 or kt[1] > 0.0 or kt[2] > 0.0:
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
            kr = kr + kt
        kt = wp.vec3(0.0)
    return kr, kt, tdir, tir


@wp.func(inline=True)
def miss_radiance(scene: SceneData) -> wp.vec3:
    """What a ray that leaves the scene returns: the background, or in fog the fog colour."""
    if scene.fog_density > 0.0:
        return scene.fog_color
    return scene.background


@wp.func(inline=True)
def fog_transmittance(scene: SceneData, t: float) -> float:
    """e^(-density t) over a ray's distance t to its hit (1 without fog)."""
    if scene.fog_density > 0.0:
        return wp.exp(-scene.fog_density * t)
    return 1.0
