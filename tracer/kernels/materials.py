"""Phong BRDF, mirror and refraction directions, exact Fresnel, textures and bump maps.

The Phong model of the lecture as an energy-conserving BRDF (docs/scene-format.md, "Materials"):
f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha), alpha between the mirrored light direction and
the view direction. A light of radiance scale E (f_att I, or a directional irradiance) gives
E cos(theta) f; the two parts are returned separately so the ray tree can show them.
"""

import warp as wp

from tracer.kernels.geometry import PI
from tracer.kernels.kinds import BUMP_IMAGE, BUMP_NOISE, TEX_CHECKER, TEX_IMAGE
from tracer.kernels.structs import MaterialData, SceneData

NOISE_SEED = wp.constant(wp.uint32(1234567))
NOISE_STEP = wp.constant(1.0e-3)  # central differences of the noise bump's height, in noise cells
CHECKER_NUDGE = wp.constant(1.0e-4)  # a point on a checker cell's boundary is moved this share of a cell along N


@wp.func
def reflect(d: wp.vec3, n: wp.vec3) -> wp.vec3:
    """Mirror direction of d about the unit normal n."""
    return d - 2.0 * wp.dot(d, n) * n


@wp.func
def refract(d: wp.vec3, n: wp.vec3, eta: float):
    """Snell's law. d unit, n unit facing d (dot(d, n) < 0), eta = n_incident / n_transmitted.

    Returns (transmitted unit direction, 1) or (zero, 0) under total internal reflection.
    """
    cos_i = wp.min(-wp.dot(d, n), 1.0)
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    if sin2_t >= 1.0:
        return wp.vec3(0.0), 0
    cos_t = wp.sqrt(1.0 - sin2_t)
    return wp.normalize(eta * d + (eta * cos_i - cos_t) * n), 1


@wp.func
def fresnel_dielectric(cos_i: float, eta: float) -> float:
    """Exact unpolarised Fresnel reflectance R = (rs^2 + rp^2) / 2, eta = n_i / n_t; 1 under TIR."""
    ci = wp.clamp(cos_i, 0.0, 1.0)
    sin2_t = eta * eta * (1.0 - ci * ci)
    if sin2_t >= 1.0:
        return 1.0
    ct = wp.sqrt(1.0 - sin2_t)
    rs = (eta * ci - ct) / (eta * ci + ct)
    rp = (ci - eta * ct) / (ci + eta * ct)
    return 0.5 * (rs * rs + rp * rp)


@wp.func
def phong_terms(kd: wp.vec3, ks: wp.vec3, shininess: float, n: wp.vec3, l: wp.vec3, v: wp.vec3):
    """(kd / pi cos(theta), ks (n+2)/(2 pi) cos^n(alpha) cos(theta)); multiply by the light's E."""
    cos_theta = wp.max(wp.dot(n, l), 0.0)
    r_l = 2.0 * wp.dot(n, l) * n - l
    cos_alpha = wp.max(wp.dot(r_l, v), 0.0)
    spec = float(0.0)
    if cos_alpha > 0.0 and (ks[0] > 0.0 or ks[1] > 0.0 or ks[2] > 0.0):
        spec = (shininess + 2.0) / (2.0 * PI) * wp.pow(cos_alpha, shininess) * cos_theta
    return kd * (cos_theta / PI), ks * spec


@wp.func(inline=True)
def image_texel(scene: SceneData, image: int, uv: wp.vec2) -> wp.vec3:
    """Bilinear lookup, repeating; uv (0, 0) is the image's lower-left corner."""
    info = scene.tex_info[image]
    w = info[1]
    h = info[2]
    x = (uv[0] - wp.floor(uv[0])) * float(w) - 0.5
    y = (1.0 - (uv[1] - wp.floor(uv[1]))) * float(h) - 0.5
    x0 = wp.floor(x)
    y0 = wp.floor(y)
    fx = x - x0
    fy = y - y0
    ix0 = (int(x0) % w + w) % w
    iy0 = (int(y0) % h + h) % h
    ix1 = (ix0 + 1) % w
    iy1 = (iy0 + 1) % h
    o = info[0]
    c00 = scene.tex_pixels[o + iy0 * w + ix0]
    c10 = scene.tex_pixels[o + iy0 * w + ix1]
    c01 = scene.tex_pixels[o + iy1 * w + ix0]
    c11 = scene.tex_pixels[o + iy1 * w + ix1]
    return (1.0 - fy) * ((1.0 - fx) * c00 + fx * c10) + fy * ((1.0 - fx) * c01 + fx * c11)


@wp.func(inline=True)
def checker(m: MaterialData, p: wp.vec3, ng: wp.vec3) -> wp.vec3:
    """Solid 3D checker; a point on a cell boundary takes the cell on its geometric normal's side."""
    q = (p + (CHECKER_NUDGE * m.tex_size) * ng) / m.tex_size
    c = int(wp.floor(q[0])) + int(wp.floor(q[1])) + int(wp.floor(q[2]))
    if (c % 2 + 2) % 2 == 0:
        return m.tex_c1
    return m.tex_c2


@wp.func(inline=True)
def diffuse_color(scene: SceneData, m: MaterialData, p: wp.vec3, ng: wp.vec3, uv: wp.vec2) -> wp.vec3:
    """kd after texturing."""
    if m.tex == TEX_CHECKER:
        return checker(m, p, ng)
    if m.tex == TEX_IMAGE:
        return image_texel(scene, m.tex_image, wp.cw_mul(uv, m.tex_scale))
    return m.kd


@wp.func
def luminance(c: wp.vec3) -> float:
    """Relative luminance Y of linear RGB (Rec. 709 primaries)."""
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


@wp.func(inline=True)
def bump_normal(
    scene: SceneData, m: MaterialData, p: wp.vec3, n: wp.vec3, uv: wp.vec2, dpdu: wp.vec3, dpdv: wp.vec3
) -> wp.vec3:
    """The normal n perturbed by the material's bump map (Blinn 1978); n unchanged without one.

    noise: height h(p) = strength * perlin(scale p), N' = normalize(N - surface gradient of h).
    image: height h(u, v) = strength * luminance(image(uv)), N' = normalize(Pu' x Pv') for the
    displaced surface P + h N (the image is read at its texel spacing for the derivatives).
    """
    if m.bump == BUMP_NOISE:
        e = NOISE_STEP
        q = p * m.bump_scale
        gx = wp.noise(NOISE_SEED, q + wp.vec3(e, 0.0, 0.0)) - wp.noise(NOISE_SEED, q - wp.vec3(e, 0.0, 0.0))
        gy = wp.noise(NOISE_SEED, q + wp.vec3(0.0, e, 0.0)) - wp.noise(NOISE_SEED, q - wp.vec3(0.0, e, 0.0))
        gz = wp.noise(NOISE_SEED, q + wp.vec3(0.0, 0.0, e)) - wp.noise(NOISE_SEED, q - wp.vec3(0.0, 0.0, e))
        g = wp.vec3(gx, gy, gz) * (m.bump_strength * m.bump_scale / (2.0 * e))
        gs = g - wp.dot(g, n) * n
        return wp.normalize(n - gs)
    if m.bump == BUMP_IMAGE:
        info = scene.tex_info[m.bump_image]
        su = m.bump_uvscale[0]
        sv = m.bump_uvscale[1]
        du = 1.0 / float(info[1])
        dv = 1.0 / float(info[2])
        st = wp.vec2(uv[0] * su, uv[1] * sv)
        h0 = luminance(image_texel(scene, m.bump_image, st))
        hu = (luminance(image_texel(scene, m.bump_image, st + wp.vec2(du, 0.0))) - h0) / du * su * m.bump_strength
        hv = (luminance(image_texel(scene, m.bump_image, st + wp.vec2(0.0, dv))) - h0) / dv * sv * m.bump_strength
        c = wp.cross(dpdu, dpdv)
        if wp.length(c) < 1.0e-12:
            return n
        nu = wp.normalize(c)
        b = c + hu * wp.cross(nu, dpdv) - hv * wp.cross(nu, dpdu)
        nb = wp.normalize(b)
        if wp.dot(nu, n) < 0.0:
            nb = -nb
        return nb
    return n
