"""Lights at a shading point: point, directional and spot lights, and sampled area lights.

A point light of intensity I (W/sr) at distance d gives E = f_att I with
f_att = 1 / (c1 + c2 d + c3 d^2); a directional light gives its irradiance; a spot light
multiplies by cos(psi)^falloff inside its cone (psi between its axis and the direction to the
point) and gives nothing outside. Shadow rays are cast only where a light can contribute.

An area light is sampled at points y (stratified by the caller): each sample acts as a point
light of intensity radiance A cos(theta_y) with inverse-square fall-off (docs/scene-format.md, "Area lights"), that
is E = radiance / pdf_omega with pdf_omega = d^2 / (A cos(theta_y)) the solid-angle density of y.
A sphere light is sampled inside the cone it subtends (same expectation, far less noise).

Everything about a light type is here but its model (tracer/scene/lights.py: the fields, and whether it is
an area light): its kind, its LightData, an area light's own shape, and the @wp.func code that
lights a point with it, samples it and (radiosity) shoots from its surface.
"""

import math
from enum import IntEnum

import numpy as np
import warp as wp

from tracer.kernels.geometry import PI, basis, intersect_sphere
from tracer.kernels.kinds import T_FAR, Shape
from tracer.kernels.sampling import concentric_disk, sample_cone, to_world
from tracer.kernels.structs import LightData, unit, vec3
from tracer.scene import LIGHT_TYPES

# The scene format's light types, numbered in its order (LightData.kind).
LightKind = IntEnum("LightKind", [(t.upper(), k) for k, t in enumerate(LIGHT_TYPES)], module=__name__)
LIGHT_DIRECTIONAL = wp.constant(int(LightKind.DIRECTIONAL))
LIGHT_SPOT = wp.constant(int(LightKind.SPOT))
LIGHT_QUAD = wp.constant(int(LightKind.QUAD))
LIGHT_DISK = wp.constant(int(LightKind.DISK))
LIGHT_SPHERE = wp.constant(int(LightKind.SPHERE))


def light_data(light) -> LightData:
    """A light of the scene (tracer/scene/lights.py) as the kernels read it."""
    d = LightData()
    d.kind = int(LightKind[light.type.upper()])
    d.position, d.direction = wp.vec3(0.0), wp.vec3(0.0, -1.0, 0.0)
    d.intensity, d.attenuation = wp.vec3(0.0), wp.vec3(0.0, 0.0, 1.0)
    d.cos_cutoff, d.falloff = -1.0, 0.0
    d.edge1, d.edge2, d.radius, d.area, d.shape = wp.vec3(0.0), wp.vec3(0.0), 0.0, 0.0, -1
    if light.type == "point":
        d.position, d.intensity, d.attenuation = vec3(light.position), vec3(light.intensity), vec3(light.attenuation)
    elif light.type == "directional":
        d.direction, d.intensity = vec3(unit(light.direction)), vec3(light.irradiance)
    elif light.type == "spot":
        d.position, d.direction = vec3(light.position), vec3(unit(light.direction))
        d.intensity, d.attenuation = vec3(light.intensity), vec3(light.attenuation)
        d.cos_cutoff, d.falloff = math.cos(math.radians(light.cutoff)), float(light.falloff)
    elif light.type == "quad":
        n = np.cross(light.edge1, light.edge2)
        d.position, d.edge1, d.edge2 = vec3(light.corner), vec3(light.edge1), vec3(light.edge2)
        d.direction, d.area, d.intensity = vec3(unit(n)), float(np.linalg.norm(n)), vec3(light.radiance)
    elif light.type == "disk":
        d.position, d.direction, d.radius = vec3(light.center), vec3(unit(light.normal)), float(light.radius)
        d.area, d.intensity = math.pi * light.radius**2, vec3(light.radiance)
    elif light.type == "sphere":
        d.position, d.radius = vec3(light.center), float(light.radius)
        d.area, d.intensity = 4 * math.pi * light.radius**2, vec3(light.radiance)
    return d


def light_shape(light) -> tuple[Shape, dict]:
    """An area light's own surface, which rays see: its Shape kind and where it is (p0, p1, p2, radius
    as ShapeData holds them)."""
    if light.type == "quad":
        return Shape.QUAD, {"p0": light.corner, "p1": light.edge1, "p2": light.edge2}
    if light.type == "disk":
        return Shape.DISK, {"p0": light.center, "p1": unit(light.normal), "radius": light.radius}
    if light.type == "sphere":
        return Shape.SPHERE, {"p0": light.center, "radius": light.radius}
    raise ValueError(f"a {light.type} light has no surface")


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
def surface_point(light: LightData, u1: float, u2: float):
    """A uniform point of an area light's surface (by area) for (u1, u2) in [0,1)^2, and the normal of
    its emitting side there: (point, unit normal)."""
    if light.kind == LIGHT_QUAD:
        return light.position + u1 * light.edge1 + u2 * light.edge2, light.direction
    if light.kind == LIGHT_DISK:
        dsk = concentric_disk(u1, u2)
        tu, tv = basis(light.direction)
        return light.position + light.radius * (dsk[0] * tu + dsk[1] * tv), light.direction
    z = 1.0 - 2.0 * u1  # the sphere: a uniform point of its surface, emitting outwards
    rr = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = 2.0 * PI * u2
    n = wp.vec3(rr * wp.cos(phi), rr * wp.sin(phi), z)
    return light.position + light.radius * n, n


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
    y, n = surface_point(light, u1, u2)
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
