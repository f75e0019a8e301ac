"""Lights at a shading point: point, directional and spot lights, and sampled area lights.

A point light of intensity I (W/sr) at distance d gives E = f_att I with
f_att = 1 / (c1 + c2 d + c3 d^2); a directional light gives its irradiance; a spot light
multiplies by cos(psi)^falloff inside its cone (psi between its axis and the direction to the
point) and gives nothing outside. Shadow rays are cast only where a light can contribute.

An area light is sampled at points y (stratified by the caller): each sample acts as a point
light of intensity radiance A cos(theta_y) with inverse-square fall-off (docs/scene-format.md, "Area lights"), that
is E = radiance / pdf_omega with pdf_omega = d^2 / (A cos(theta_y)) the solid-angle density of y.
A sphere light is sampled inside the cone it subtends (same expectation, far less noise).
"""

import warp as wp

from tracer.geometry import PI, basis, intersect_sphere
from tracer.kinds import LIGHT_DIRECTIONAL, LIGHT_DISK, LIGHT_QUAD, LIGHT_SPHERE, LIGHT_SPOT, T_FAR
from tracer.sampling import concentric_disk, sample_cone, to_world
from tracer.structs import LightData


@wp.func(inline=True)
def is_area_light(light: LightData) -> bool:
    return light.kind == LIGHT_QUAD or light.kind == LIGHT_DISK or light.kind == LIGHT_SPHERE


@wp.func(inline=True)
def light_at(light: LightData, p: wp.vec3):
    """Point, directional, spot: (unit direction from p to the light, distance, E, 1 if it reaches p)."""
    if light.kind == LIGHT_DIRECTIONAL:
        return -light.direction, T_FAR, light.intensity, 1
    to_light = light.position - p
    dist = wp.length(to_light)
    if dist <= 0.0:
        return wp.vec3(0.0, 1.0, 0.0), 0.0, wp.vec3(0.0), 0
    l = to_light / dist
    a = light.attenuation
    e = light.intensity / (a[0] + a[1] * dist + a[2] * dist * dist)
    if light.kind == LIGHT_SPOT:
        cos_psi = wp.dot(-l, light.direction)
        if cos_psi < light.cos_cutoff:
            return l, dist, wp.vec3(0.0), 0
        e = e * wp.pow(wp.max(cos_psi, 0.0), light.falloff)
    return l, dist, e, 1


@wp.func(inline=True)
def sphere_cone_cos(light: LightData, p: wp.vec3) -> float:
    """cos of the half-angle of the cone the sphere light subtends from p (2 if p is inside)."""
    dc = wp.length(light.position - p)
    if dc <= light.radius:
        return 2.0
    sin2 = (light.radius / dc) * (light.radius / dc)
    return wp.sqrt(wp.max(0.0, 1.0 - sin2))


@wp.func(inline=True)
def sample_area_light(light: LightData, p: wp.vec3, u1: float, u2: float):
    """A point y of an area light seen from p: (unit direction, distance to y, E = radiance / pdf,
    pdf in solid angle, 1 if y emits towards p else 0)."""
    if light.kind == LIGHT_SPHERE:
        cos_max = sphere_cone_cos(light, p)
        if cos_max > 1.0:
            return wp.vec3(0.0, 1.0, 0.0), 0.0, wp.vec3(0.0), 0.0, 0
        axis = wp.normalize(light.position - p)
        l = to_world(sample_cone(u1, u2, cos_max), axis)
        t = intersect_sphere(p, l, light.position, light.radius, T_FAR)
        if t < 0.0:  # grazing the silhouette in float arithmetic: the tangent distance
            t = wp.length(light.position - p) * cos_max
        one_minus = (1.0 - cos_max * cos_max) / (1.0 + cos_max)
        pdf = 1.0 / (2.0 * PI * one_minus)
        return l, t, light.intensity / pdf, pdf, 1
    y = wp.vec3(0.0)
    if light.kind == LIGHT_QUAD:
        y = light.position + u1 * light.edge1 + u2 * light.edge2
    else:
        dsk = concentric_disk(u1, u2)
        tu, tv = basis(light.direction)
        y = light.position + light.radius * (dsk[0] * tu + dsk[1] * tv)
    to_y = y - p
    dist = wp.length(to_y)
    if dist <= 0.0:
        return wp.vec3(0.0, 1.0, 0.0), 0.0, wp.vec3(0.0), 0.0, 0
    l = to_y / dist
    cos_y = wp.dot(light.direction, -l)
    if cos_y <= 0.0:  # p is behind the emitting side
        return l, dist, wp.vec3(0.0), 0.0, 0
    pdf = dist * dist / (light.area * cos_y)
    return l, dist, light.intensity / pdf, pdf, 1


@wp.func(inline=True)
def area_light_pdf(light: LightData, p: wp.vec3, l: wp.vec3, t: float) -> float:
    """Solid-angle density with which sample_area_light picks direction l from p (hit at distance t)."""
    if light.kind == LIGHT_SPHERE:
        cos_max = sphere_cone_cos(light, p)
        if cos_max > 1.0:
            return 0.0
        return 1.0 / (2.0 * PI * (1.0 - cos_max * cos_max) / (1.0 + cos_max))
    cos_y = wp.dot(light.direction, -l)
    if cos_y <= 0.0:
        return 0.0
    return t * t / (light.area * cos_y)
