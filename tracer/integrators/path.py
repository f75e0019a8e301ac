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
from tracer.integrators.record import F_FOG, I_END, TreeRecord, begin_node, record_hit, record_miss, record_terms
from tracer.integrators.whitted import shadow_node
from tracer.kinds import (
    END_ABSORBED,
    END_MAX_DEPTH,
    RAY_EYE,
    RAY_REFLECTION,
    RAY_SHADOW,
    RAY_TRANSMISSION,
    T_FAR,
)
from tracer.lights import area_light_pdf, is_area_light
from tracer.materials import phong_terms, reflect
from tracer.sampling import (
    cos_lobe_pdf,
    cosine_hemisphere_pdf,
    sample_2d,
    sample_cos_lobe,
    sample_cosine_hemisphere,
    to_world,
)
from tracer.structs import SceneData

RR_DEPTH = wp.constant(5)  # Russian roulette from this depth on
DIMS_PER_BOUNCE = wp.constant(1024)  # low-discrepancy dimensions of a bounce: BSDF, lobe, then one per light


@wp.func
def power_heuristic(nf: float, pf: float, ng: float, pg: float) -> float:
    a = nf * pf
    b = ng * pg
    if a <= 0.0:
        return 0.0
    return (a * a) / (a * a + b * b)


@wp.func
def continuous_pdf(pd: float, ps: float, shininess: float, n: wp.vec3, r: wp.vec3, wi: wp.vec3) -> float:
    """Density of direction wi under the diffuse + Phong mixture (lobe choice included)."""
    pdf = pd * cosine_hemisphere_pdf(wp.dot(n, wi))
    if ps > 0.0:
        pdf += ps * cos_lobe_pdf(wp.dot(r, wi), shininess)
    return pdf


@wp.func
def trace(
    scene: SceneData,
    o: wp.vec3,
    d: wp.vec3,
    time: float,
    rng: wp.uint32,
    key: wp.uint32,
    sample: int,
    record: int,
    rec: TreeRecord,
) -> SampleOut:
    """One path from the eye ray (o, d): its radiance estimate, its rays by kind, its first hit."""
    out = SampleOut()
    out.color = wp.vec3(0.0)
    out.counts = wp.vec4i(0)
    out.depth = 0.0
    out.normal = wp.vec3(0.0)
    out.albedo = wp.vec3(0.0)
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
        m = s.m
        n = s.n
        v = -rd
        if kind == RAY_EYE:
            out.depth = h.t
            out.normal = n
            out.albedo = s.kd
        if node >= 0:
            record_hit(rec, node, h.t, h.p, n, h.obj, h.mat, s.front)
            rec.floats[node, F_FOG] = fog_t
        tb = beta * fog_t  # throughput at the surface

        # emission, MIS-weighted against light sampling when an area light is reached by a sampled direction
        emission = s.emission
        if h.light >= 0 and delta_before == 0 and max3(emission) > 0.0:
            pl = area_light_pdf(scene.lights[h.light], p_before, rd, h.t)
            emission = emission * power_heuristic(1.0, pdf_before, float(scene.light_samples), pl)

        # the continuous lobes: diffuse and the Phong highlight; their selection weights
        rdir = wp.normalize(reflect(rd, n))
        wd = max3(s.kd)
        ws = max3(m.ks)
        diffuse = wp.vec3(0.0)
        specular = wp.vec3(0.0)

        # Fresnel and total internal reflection give the discrete lobes' weights (as in `whitted`)
        kr, kt, tdir, tir = scatter_weights(m, rd, n, s.front)
        wr = max3(kr)
        wt = max3(kt)
        total = wd + ws + wr + wt
        pd = float(0.0)
        ps = float(0.0)
        if total > 0.0:
            pd = wd / total
            ps = ws / total

        # next-event estimation towards every light
        if wd + ws > 0.0:
            for li in range(scene.num_lights):
                light = scene.lights[li]
                area = is_area_light(light)
                n_rays = wp.where(area, scene.light_samples, 1)
                for k in range(n_rays):
                    # the k-th of the pixel's (sample x light_samples) points on this light, evenly spread
                    u = sample_2d(key, depth * DIMS_PER_BOUNCE + 2 + li, sample * n_rays + k)
                    l, dist, e, pl, reaches = light_sample(light, h.p, u, n_rays)
                    mis = float(1.0)
                    if area:
                        mis = power_heuristic(float(n_rays), pl, 1.0, continuous_pdf(pd, ps, m.shininess, n, rdir, l))
                    if reaches != 0 and wp.dot(n, l) > 0.0:
                        so = offset_origin(h.p, s.nf, l)
                        out.counts[RAY_SHADOW] = out.counts[RAY_SHADOW] + 1
                        sh = shadow_test(scene, so, l, shadow_reach(scene, light, so, l, dist), time, record)
                        blocked = sh.hit
                        dterm, sterm = phong_terms(s.kd, m.ks, m.shininess, n, l, v)
                        dterm = wp.cw_mul(e, dterm) * mis
                        sterm = wp.cw_mul(e, sterm) * mis
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
                                tb,
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
        local = emission + diffuse + specular
        out.color += wp.cw_mul(tb, local)
        if node >= 0:
            record_terms(rec, node, emission, wp.vec3(0.0), diffuse, specular)

        # the extension ray
        end = int(-1)
        if depth + 1 > scene.max_depth:
            end = END_MAX_DEPTH
        elif total <= 0.0:
            end = END_ABSORBED
        else:
            u0 = sample_2d(key, depth * DIMS_PER_BOUNCE + 1, sample)[0]  # which lobe
            uv = sample_2d(key, depth * DIMS_PER_BOUNCE, sample)  # where in it
            u1 = uv[0]
            u2 = uv[1]
            factor = wp.vec3(0.0)
            wi = wp.vec3(0.0)
            next_kind = int(RAY_REFLECTION)
            if u0 < pd + ps:
                # one sample of the continuous mixture: f cos / (pd pdf_d + ps pdf_s)
                if u0 < pd:
                    wi = to_world(sample_cosine_hemisphere(u1, u2), n)
                else:
                    wi = to_world(sample_cos_lobe(u1, u2, m.shininess), rdir)
                pdf = continuous_pdf(pd, ps, m.shininess, n, rdir, wi)
                if wp.dot(wi, s.nf) > 0.0 and wp.dot(wi, n) > 0.0 and pdf > 0.0:
                    dterm, sterm = phong_terms(s.kd, m.ks, m.shininess, n, wi, v)
                    factor = (dterm + sterm) / pdf
                delta_before = 0
                pdf_before = pdf
            elif u0 < pd + ps + wr / total:
                wi = glossy_direction(rdir, m.gloss, u1, u2)
                if wp.dot(wi, s.nf) > 0.0 or m.gloss <= 0.0:
                    factor = kr * (total / wr)
                delta_before = 1
            else:
                wi = glossy_direction(tdir, m.gloss, u1, u2)
                next_kind = RAY_TRANSMISSION
                if wp.dot(wi, s.nf) < 0.0 or m.gloss <= 0.0:
                    factor = kt * (total / wt)
                delta_before = 1
            if depth >= RR_DEPTH:  # Russian roulette
                q = wp.min(0.95, max3(wp.cw_mul(tb, factor)))
                if wp.randf(state) >= q:
                    factor = wp.vec3(0.0)
                else:
                    factor = factor / q
            if max3(factor) <= 0.0:
                end = END_ABSORBED
            else:
                k_ray = factor
                beta = wp.cw_mul(tb, factor)
                p_before = h.p
                ro = offset_origin(h.p, s.nf, wi)
                rd = wi
                kind = next_kind
                parent = node
                depth = depth + 1
        if end >= 0:
            if node >= 0:
                rec.ints[node, I_END] = end
            depth = 0
    return out
