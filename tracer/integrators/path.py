"""Path tracing (Kajiya 1986) with the same Phong materials: diffuse interreflection.

At each hit: emission (weighted by multiple importance sampling when an area light is reached by
a sampled direction), next-event estimation towards every light (point, spot and directional
lights exactly; area lights with `light_samples` stratified samples, MIS power heuristic against
BSDF sampling, Veach & Guibas 1995), then one extension ray drawn from the material's lobes:
diffuse (cosine-weighted hemisphere) and the Phong highlight (a cos^n lobe about the mirror
direction) as one continuous mixture, the mirror (kr) and refraction (kt, Fresnel, total internal
reflection) as discrete lobes, or cos^m lobes about them when `gloss` is set. Russian roulette
ends paths after five bounces with probability 1 - max(throughput) (as Mitsuba 3 does). The light and BSDF samples of
a pixel's successive samples follow Roberts' R2 low-discrepancy sequence (randomly shifted per
pixel and dimension), which spreads them more evenly than independent random numbers: the same
image with less noise. No ambient term: light that
bounces between diffuse surfaces is what this integrator adds to the ray tree's picture.

`trace` reads like the lecture's Shade(): the hit, its emission, the direct light, a direction chosen from
the lobes, Russian roulette, and on. What a path carries from one bounce to the next is a `PathRay`; the
material's lobes at a hit are a `Lobes`.

max_depth = N bounces: the eye ray has depth 1, and a path has at most N + 1 segments (the last
one a shadow ray), so max_depth 1 is direct light only, exactly as in the `whitted` integrator.
"""

import warp as wp

from tracer.integrators.common import (
    SampleOut,
    Stack,
    Surface,
    fog_transmittance,
    glossy_direction,
    max3,
    miss_radiance,
    no_sample,
    offset_origin,
    scatter_weights,
    surface_at,
)
from tracer.integrators.direct import direct_light
from tracer.integrators.record import TreeRecord, begin_node, record_end, record_hit, record_miss, record_terms
from tracer.kernels.geometry import Hit, closest_hit
from tracer.kernels.kinds import (
    END_ABSORBED,
    END_MAX_DEPTH,
    RAY_EYE,
    RAY_REFLECTION,
    RAY_SHADOW,
    RAY_TRANSMISSION,
    T_FAR,
)
from tracer.kernels.lights import area_light_pdf
from tracer.kernels.materials import phong_terms, reflect
from tracer.kernels.sampling import (
    phong_lobes_pdf,
    power_heuristic,
    sample_2d,
    sample_cos_lobe,
    sample_cosine_hemisphere,
    to_world,
)
from tracer.kernels.structs import SceneData

RR_DEPTH = wp.constant(5)  # Russian roulette from this depth on
RR_MAX_SURVIVAL = wp.constant(0.95)  # a path survives the roulette with probability min(this, max(throughput))
# Low-discrepancy dimensions (sampling.sample_2d) of the bounce at depth d: d * DIMS_PER_BOUNCE + one of these
DIMS_PER_BOUNCE = wp.constant(1024)
DIM_BSDF = wp.constant(0)  # where in the chosen lobe the extension ray goes
DIM_LOBE = wp.constant(1)  # which lobe
DIM_LIGHTS = wp.constant(2)  # light li's points: DIM_LIGHTS + li


@wp.struct
class PathRay:
    """The ray a path goes on with, what it carries, and how its direction was chosen (the MIS of the
    emission it reaches)."""

    o: wp.vec3  # origin
    d: wp.vec3  # unit direction
    kind: int  # RAY_*
    depth: int  # 1 for the eye ray, one more per bounce; 0 once the path has ended
    beta: wp.vec3  # throughput: product of f cos / pdf along the path up to this ray
    k: wp.vec3  # this ray's own factor of beta (the ray tree's k)
    parent: int  # the ray tree's node of the ray before (-1: none)
    delta: int  # 1 when its direction came from the camera or a discrete/glossy lobe
    pdf: float  # else the direction's density under the continuous lobes
    p: wp.vec3  # the point it left (the eye ray: its origin)


@wp.struct
class Lobes:
    """The material's lobes at a hit, chosen in proportion to their largest weight: diffuse and the Phong
    highlight (continuous), the mirror and refraction (discrete, with Fresnel and total internal reflection)."""

    kr: wp.vec3  # the mirror's weight (with Fresnel)
    kt: wp.vec3  # refraction's weight (with Fresnel; 0 under total internal reflection)
    tdir: wp.vec3  # the refracted direction
    rdir: wp.vec3  # the mirror direction, for the Phong lobe and the mirror (a diffuse surface has neither)
    pd: float  # probability of the diffuse lobe
    ps: float  # probability of the Phong lobe
    total: float  # the sum of the four weights (0: the surface absorbs everything)


@wp.func(inline=True)
def eye_path(o: wp.vec3, d: wp.vec3) -> PathRay:
    """The path's first ray: the eye ray (o, d), throughput 1."""
    ray = PathRay()
    ray.o = o
    ray.d = d
    ray.kind = RAY_EYE
    ray.depth = 1
    ray.beta = wp.vec3(1.0)
    ray.k = wp.vec3(1.0)
    ray.parent = -1
    ray.delta = 1
    ray.pdf = 0.0
    ray.p = o
    return ray


@wp.func(inline=True)
def lobes_at(s: Surface, rd: wp.vec3) -> Lobes:
    """The lobes at s for a ray arriving along rd."""
    lb = Lobes()
    kr, kt, tdir, tir = scatter_weights(s.m, rd, s.n, s.front)
    lb.kr = kr
    lb.kt = kt
    lb.tdir = tdir
    wd = max3(s.kd)
    ws = max3(s.m.ks)
    lb.rdir = wp.vec3(0.0)
    if ws > 0.0 or max3(kr) > 0.0:
        lb.rdir = wp.normalize(reflect(rd, s.n))
    lb.total = wd + ws + max3(kr) + max3(kt)
    lb.pd = 0.0
    lb.ps = 0.0
    if lb.total > 0.0:
        lb.pd = wd / lb.total
        lb.ps = ws / lb.total
    return lb


@wp.func(inline=True)
def emission_seen(scene: SceneData, h: Hit, s: Surface, ray: PathRay) -> wp.vec3:
    """The surface's emission towards the ray, MIS-weighted against light sampling when an area light is
    reached by a sampled direction (power heuristic, Veach & Guibas 1995)."""
    emission = s.emission
    if h.light >= 0 and ray.delta == 0 and max3(emission) > 0.0:
        pl = area_light_pdf(scene.lights[h.light], ray.p, ray.d, h.t)
        emission = emission * power_heuristic(1.0, ray.pdf, float(scene.light_samples), pl)
    return emission


@wp.func(inline=True)
def sample_lobes(s: Surface, rd: wp.vec3, lb: Lobes, u0: float, u1: float, u2: float):
    """The extension ray's direction from the material's lobes, u0 choosing the lobe (diffuse with
    probability lb.pd, the Phong lobe about the mirror direction lb.rdir with lb.ps, the mirror and the
    refraction (lb.tdir) in proportion to max(kr) and max(kt) of lb.total) and (u1, u2) the direction in it:
    (direction, factor f cos / pdf (zero for a direction on the wrong side), RAY_* kind, 1 for a discrete
    or glossy lobe, the density of the direction under the continuous lobes)."""
    m = s.m
    factor = wp.vec3(0.0)
    wi = wp.vec3(0.0)
    kind = int(RAY_REFLECTION)
    delta = int(1)
    pdf = float(0.0)
    if u0 < lb.pd + lb.ps:
        # one sample of the continuous mixture: f cos / (pd pdf_d + ps pdf_s)
        if u0 < lb.pd:
            wi = to_world(sample_cosine_hemisphere(u1, u2), s.n)
        else:
            wi = to_world(sample_cos_lobe(u1, u2, m.shininess), lb.rdir)
        pdf = phong_lobes_pdf(lb.pd, lb.ps, m.shininess, s.n, lb.rdir, wi)
        if wp.dot(wi, s.nf) > 0.0 and wp.dot(wi, s.n) > 0.0 and pdf > 0.0:
            if lb.ps > 0.0:
                dterm, sterm = phong_terms(s.kd, m.ks, m.shininess, s.n, wi, -rd)
                factor = (dterm + sterm) / pdf
            else:  # Lambertian: f cos / pdf = (kd / pi) cos / (pd cos / pi)
                factor = s.kd / lb.pd
        delta = 0
    elif u0 < lb.pd + lb.ps + max3(lb.kr) / lb.total:
        wi = glossy_direction(lb.rdir, m.gloss, u1, u2)
        if wp.dot(wi, s.nf) > 0.0 or m.gloss <= 0.0:
            factor = lb.kr * (lb.total / max3(lb.kr))
    else:
        wi = glossy_direction(lb.tdir, m.gloss, u1, u2)
        kind = RAY_TRANSMISSION
        if wp.dot(wi, s.nf) < 0.0 or m.gloss <= 0.0:
            factor = lb.kt * (lb.total / max3(lb.kt))
    return wi, factor, kind, delta, pdf


@wp.func(inline=True)
def russian_roulette(factor: wp.vec3, tb: wp.vec3, rng: wp.uint32):
    """The path goes on with probability q = min(0.95, max(tb factor)), its factor divided by q, or ends (a
    zero factor): (factor, rng after its draw). Unbiased: the expected factor is q (factor / q) = factor."""
    state = wp.uint32(rng)
    q = wp.min(RR_MAX_SURVIVAL, max3(wp.cw_mul(tb, factor)))
    if wp.randf(state) >= q:
        return wp.vec3(0.0), state
    return factor / q, state


@wp.func(inline=True)
def choose_direction(
    scene: SceneData, s: Surface, rd: wp.vec3, depth: int, lb: Lobes, key: wp.uint32, dims: int, sample: int
):
    """The extension ray's direction at s (depth: the arriving ray's) from the lobes, at the pixel's R2 points
    of the bounce's dimensions `dims`, or why the path ends here: (END_* or -1, then as sample_lobes)."""
    if depth + 1 > scene.max_depth:
        return END_MAX_DEPTH, wp.vec3(0.0), wp.vec3(0.0), int(RAY_REFLECTION), 1, 0.0
    if lb.total <= 0.0:
        return END_ABSORBED, wp.vec3(0.0), wp.vec3(0.0), int(RAY_REFLECTION), 1, 0.0
    u0 = float(0.0)
    if lb.pd + lb.ps < 1.0:  # a choice between lobes to make (a purely diffuse or Phong material has none)
        u0 = sample_2d(key, dims + DIM_LOBE, sample)[0]
    uv = sample_2d(key, dims + DIM_BSDF, sample)
    wi, factor, kind, delta, pdf = sample_lobes(s, rd, lb, u0, uv[0], uv[1])
    return -1, wi, factor, kind, delta, pdf


@wp.func(inline=True)
def next_ray(
    end: int,
    p: wp.vec3,
    nf: wp.vec3,
    wi: wp.vec3,
    kind: int,
    delta: int,
    pdf: float,
    depth: int,
    tb: wp.vec3,
    factor: wp.vec3,
    node: int,
) -> PathRay:
    """The extension ray from hit p (geometric normal nf) along wi, of RAY_* kind, chosen as `delta` and `pdf`
    say, at depth + 1: its throughput tb factor (tb the throughput at the surface), child of the ray tree's
    `node`. Depth 0 (the path is over) when `end` says why it ends. Made whether the path goes on or not, so
    that `trace` assigns its ray once a bounce, outside any branch: a struct assigned inside a branch costs
    Warp a select of every field where the branch ends (the Cornell box ran 10 % slower so)."""
    ray = PathRay()
    ray.o = offset_origin(p, nf, wi)
    ray.d = wi
    ray.kind = kind
    ray.depth = wp.where(end >= 0, 0, depth + 1)
    ray.beta = wp.cw_mul(tb, factor)
    ray.k = factor
    ray.parent = node
    ray.delta = delta
    ray.pdf = pdf
    ray.p = p
    return ray


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
    """One path from the eye ray (o, d): its radiance estimate, its rays by kind, its first hit.
    key and sample: the pixel's low-discrepancy dimensions and this sample's index in them; rng: the
    Russian roulette. It keeps no stack."""
    out = no_sample()
    state = wp.uint32(rng)
    ray = eye_path(o, d)
    while ray.depth > 0:
        out.counts[ray.kind] = out.counts[ray.kind] + 1
        node = int(-1)
        if record != 0:
            node = begin_node(rec, ray.kind, ray.depth, ray.parent, ray.o, ray.d, ray.beta, ray.k, time)
        h = closest_hit(scene, ray.o, ray.d, T_FAR, time)
        if h.hit == 0:  # the ray leaves the scene
            out.color += wp.cw_mul(ray.beta, miss_radiance(scene))
            record_miss(rec, node, wp.where(scene.fog_density > 0.0, 1, 0))
            break
        fog_t = fog_transmittance(scene, h.t)
        if scene.fog_density > 0.0:  # what the fog scatters towards the eye on the way
            out.color += wp.cw_mul(ray.beta, (1.0 - fog_t) * scene.fog_color)
        s = surface_at(scene, h, ray.d)
        if ray.kind == RAY_EYE:  # the AOVs: the eye ray's hit
            out.depth = h.t
            out.normal = s.n
            out.albedo = s.kd
        record_hit(rec, node, h.t, h.p, s.n, h.obj, h.mat, s.front, fog_t)
        tb = ray.beta * fog_t  # throughput at the surface

        # emission, then next-event estimation towards every light (when a continuous lobe can reflect it)
        emission = emission_seen(scene, h, s, ray)
        lb = lobes_at(s, ray.d)
        lights = wp.where(max3(s.kd) + max3(s.m.ks) > 0.0, scene.num_lights, 0)
        dims = ray.depth * DIMS_PER_BOUNCE
        diffuse, specular, shadow_rays, state = direct_light(
            scene, s, -ray.d, time, lights, state, key, dims + DIM_LIGHTS, sample, lb.pd, lb.ps, lb.rdir,
            record, rec, node, ray.depth, tb,
        )  # fmt: skip
        out.counts[RAY_SHADOW] = out.counts[RAY_SHADOW] + shadow_rays
        out.color += wp.cw_mul(tb, emission + diffuse + specular)
        record_terms(rec, node, emission, wp.vec3(0.0), diffuse, specular)

        # choose a direction from the lobes, Russian roulette, and continue
        end, wi, factor, kind, delta, pdf = choose_direction(scene, s, ray.d, ray.depth, lb, key, dims, sample)
        if end < 0 and ray.depth >= RR_DEPTH:
            factor, state = russian_roulette(factor, tb, state)
        if end < 0 and max3(factor) <= 0.0:
            end = END_ABSORBED
        if end >= 0:
            record_end(rec, node, end)
        ray = next_ray(end, h.p, s.nf, wi, kind, delta, pdf, ray.depth, tb, factor, node)
    return out
