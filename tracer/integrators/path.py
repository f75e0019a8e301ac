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

max_depth = N bounces: the eye ray has depth 1, and a path has at most N + 1 segments (the last
one a shadow ray), so max_depth 1 is direct light only, exactly as in the `whitted` integrator.
"""

import warp as wp

from tracer.geometry import closest_hit
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
from tracer.kinds import END_ABSORBED, END_MAX_DEPTH, RAY_EYE, RAY_REFLECTION, RAY_SHADOW, RAY_TRANSMISSION, T_FAR
from tracer.lights import area_light_pdf
from tracer.materials import phong_terms, reflect
from tracer.sampling import (
    phong_lobes_pdf,
    power_heuristic,
    sample_2d,
    sample_cos_lobe,
    sample_cosine_hemisphere,
    to_world,
)
from tracer.structs import SceneData

RR_DEPTH = wp.constant(5)  # Russian roulette from this depth on
RR_MAX_SURVIVAL = wp.constant(0.95)  # a path survives the roulette with probability min(this, max(throughput))
# Low-discrepancy dimensions (sampling.sample_2d) of the bounce at depth d: d * DIMS_PER_BOUNCE + one of these
DIMS_PER_BOUNCE = wp.constant(1024)
DIM_BSDF = wp.constant(0)  # where in the chosen lobe the extension ray goes
DIM_LOBE = wp.constant(1)  # which lobe
DIM_LIGHTS = wp.constant(2)  # light li's points: DIM_LIGHTS + li


@wp.func(inline=True)
def sample_lobes(
    s: Surface,
    rd: wp.vec3,
    rdir: wp.vec3,
    kr: wp.vec3,
    kt: wp.vec3,
    tdir: wp.vec3,
    pd: float,
    ps: float,
    total: float,
    u0: float,
    u1: float,
    u2: float,
):
    """The extension ray's direction from the material's lobes, u0 choosing the lobe (diffuse with
    probability pd, the Phong lobe about the mirror direction rdir with ps, the mirror and the
    refraction (tdir) in proportion to max(kr) and max(kt) of `total`) and (u1, u2) the direction in it:
    (direction, factor f cos / pdf (zero for a direction on the wrong side), RAY_* kind, 1 for a discrete
    or glossy lobe, the density of the direction under the continuous lobes)."""
    m = s.m
    factor = wp.vec3(0.0)
    wi = wp.vec3(0.0)
    kind = int(RAY_REFLECTION)
    delta = int(1)
    pdf = float(0.0)
    if u0 < pd + ps:
        # one sample of the continuous mixture: f cos / (pd pdf_d + ps pdf_s)
        if u0 < pd:
            wi = to_world(sample_cosine_hemisphere(u1, u2), s.n)
        else:
            wi = to_world(sample_cos_lobe(u1, u2, m.shininess), rdir)
        pdf = phong_lobes_pdf(pd, ps, m.shininess, s.n, rdir, wi)
        if wp.dot(wi, s.nf) > 0.0 and wp.dot(wi, s.n) > 0.0 and pdf > 0.0:
            if ps > 0.0:
                dterm, sterm = phong_terms(s.kd, m.ks, m.shininess, s.n, wi, -rd)
                factor = (dterm + sterm) / pdf
            else:  # Lambertian: f cos / pdf = (kd / pi) cos / (pd cos / pi)
                factor = s.kd / pd
        delta = 0
    elif u0 < pd + ps + max3(kr) / total:
        wi = glossy_direction(rdir, m.gloss, u1, u2)
        if wp.dot(wi, s.nf) > 0.0 or m.gloss <= 0.0:
            factor = kr * (total / max3(kr))
    else:
        wi = glossy_direction(tdir, m.gloss, u1, u2)
        kind = RAY_TRANSMISSION
        if wp.dot(wi, s.nf) < 0.0 or m.gloss <= 0.0:
            factor = kt * (total / max3(kt))
    return wi, factor, kind, delta, pdf


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
    beta = wp.vec3(1.0)  # throughput: product of f cos / pdf along the path
    k_ray = wp.vec3(1.0)  # this ray's own factor of beta (the ray tree's k)
    ro = o
    rd = d
    depth = int(1)
    kind = int(RAY_EYE)
    parent = int(-1)
    delta_before = int(1)  # the previous direction came from the camera or a discrete/glossy lobe
    pdf_before = float(0.0)  # its density under the continuous lobes (for MIS of emission)
    p_before = o
    while depth > 0:
        out.counts[kind] = out.counts[kind] + 1
        node = int(-1)
        if record != 0:
            node = begin_node(rec, kind, depth, parent, ro, rd, beta, k_ray, time)
        h = closest_hit(scene, ro, rd, T_FAR, time)
        if h.hit == 0:  # the ray leaves the scene
            out.color += wp.cw_mul(beta, miss_radiance(scene))
            record_miss(rec, node, wp.where(scene.fog_density > 0.0, 1, 0))
            break
        fog_t = fog_transmittance(scene, h.t)
        if scene.fog_density > 0.0:
            out.color += wp.cw_mul(beta, (1.0 - fog_t) * scene.fog_color)
        s = surface_at(scene, h, rd)
        if kind == RAY_EYE:
            out.depth = h.t
            out.normal = s.n
            out.albedo = s.kd
        record_hit(rec, node, h.t, h.p, s.n, h.obj, h.mat, s.front, fog_t)
        tb = beta * fog_t  # throughput at the surface

        # emission, MIS-weighted against light sampling when an area light is reached by a sampled direction
        emission = s.emission
        if h.light >= 0 and delta_before == 0 and max3(emission) > 0.0:
            pl = area_light_pdf(scene.lights[h.light], p_before, rd, h.t)
            emission = emission * power_heuristic(1.0, pdf_before, float(scene.light_samples), pl)

        # the lobes, chosen in proportion to their largest weight: diffuse and the Phong highlight
        # (continuous), the mirror and refraction (discrete, with Fresnel and total internal reflection)
        kr, kt, tdir, tir = scatter_weights(s.m, rd, s.n, s.front)
        wd = max3(s.kd)
        ws = max3(s.m.ks)
        rdir = wp.vec3(0.0)  # the mirror direction, for the Phong lobe and the mirror (a diffuse surface has neither)
        if ws > 0.0 or max3(kr) > 0.0:
            rdir = wp.normalize(reflect(rd, s.n))
        total = wd + ws + max3(kr) + max3(kt)
        pd = float(0.0)
        ps = float(0.0)
        if total > 0.0:
            pd = wd / total
            ps = ws / total

        # next-event estimation towards every light (when a continuous lobe can reflect it)
        lights = wp.where(wd + ws > 0.0, scene.num_lights, 0)
        dims = depth * DIMS_PER_BOUNCE
        diffuse, specular, shadow_rays, state = direct_light(
            scene,
            s,
            -rd,
            time,
            lights,
            state,
            key,
            dims + DIM_LIGHTS,
            sample,
            pd,
            ps,
            rdir,
            record,
            rec,
            node,
            depth,
            tb,
        )
        out.counts[RAY_SHADOW] = out.counts[RAY_SHADOW] + shadow_rays
        out.color += wp.cw_mul(tb, emission + diffuse + specular)
        record_terms(rec, node, emission, wp.vec3(0.0), diffuse, specular)

        # the extension ray
        end = int(-1)
        if depth + 1 > scene.max_depth:
            end = END_MAX_DEPTH
        elif total <= 0.0:
            end = END_ABSORBED
        else:
            u0 = float(0.0)
            if pd + ps < 1.0:  # a choice between lobes to make (a purely diffuse or Phong material has none)
                u0 = sample_2d(key, dims + DIM_LOBE, sample)[0]
            uv = sample_2d(key, dims + DIM_BSDF, sample)
            wi, factor, next_kind, delta, pdf = sample_lobes(s, rd, rdir, kr, kt, tdir, pd, ps, total, u0, uv[0], uv[1])
            if depth >= RR_DEPTH:  # Russian roulette
                q = wp.min(RR_MAX_SURVIVAL, max3(wp.cw_mul(tb, factor)))
                if wp.randf(state) >= q:
                    factor = wp.vec3(0.0)
                else:
                    factor = factor / q
            if max3(factor) <= 0.0:
                end = END_ABSORBED
            else:
                k_ray = factor
                beta = wp.cw_mul(tb, factor)
                delta_before = delta
                pdf_before = pdf
                p_before = h.p
                ro = offset_origin(h.p, s.nf, wi)
                rd = wi
                kind = next_kind
                parent = node
                depth = depth + 1
        if end >= 0:
            record_end(rec, node, end)
            depth = 0
    return out
