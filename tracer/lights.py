"""Point, directional and spot lights: direction, distance and strength at a shading point.

A point light of intensity I (W/sr) at distance d gives E = f_att I with
f_att = 1 / (c1 + c2 d + c3 d^2); a directional light gives its irradiance; a spot light
multiplies by cos(psi)^falloff inside its cone (psi between its axis and the direction to the
point) and gives nothing outside. Shadow rays are cast only where a light can contribute.
"""

import warp as wp

from tracer.compile import LightData
from tracer.kinds import LIGHT_DIRECTIONAL, LIGHT_SPOT, T_FAR


@wp.func
def light_at(light: LightData, p: wp.vec3):
    """(unit direction from p to the light, distance, E, 1 if the light reaches p else 0)."""
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
