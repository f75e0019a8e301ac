"""Primary rays: the pinhole camera and the thin lens of docs/scene-format.md ("Camera rays").

direction = normalize(forward + (2(x+u)/width - 1) h aspect right + (1 - 2(y+v)/height) h up),
with h = tan(vfov / 2); pixel (x, y) counts columns from the left and rows from the top.
With a lens (Cook et al. 1984) the ray starts at a uniform point of the lens disk (radius
lens_radius, in the right/up plane at lookfrom) and passes through the point where the
pinhole ray meets the focal plane, perpendicular to forward at focus_distance: points on that
plane stay sharp, others blur in proportion to the aperture.
"""

import warp as wp

from tracer.kernels.sampling import concentric_disk
from tracer.kernels.structs import CameraData


@wp.func(inline=True)
def camera_ray(cam: CameraData, fx: float, fy: float, width: int, height: int, u1: float, u2: float):
    """Origin and unit direction through film position (fx, fy) = (x + u, y + v); (u1, u2) picks the
    point of the lens."""
    sx = (2.0 * fx / float(width) - 1.0) * cam.h * cam.aspect
    sy = (1.0 - 2.0 * fy / float(height)) * cam.h
    d = wp.normalize(cam.forward + sx * cam.right + sy * cam.up)
    if cam.lens_radius <= 0.0:
        return cam.origin, d
    focus = cam.origin + d * (cam.focus_distance / wp.dot(d, cam.forward))
    lens = concentric_disk(u1, u2) * cam.lens_radius
    o = cam.origin + lens[0] * cam.right + lens[1] * cam.up
    return o, wp.normalize(focus - o)


@wp.func(inline=True)
def shutter_time(cam: CameraData, u: float, sample: int) -> float:
    """The ray's time T = T0 + u (T1 - T0) (motion blur); with camera.instants N, the instant
    T0 + (sample mod N + 0.5) (T1 - T0) / N instead (N still frames averaged: temporal aliasing)."""
    if cam.instants > 0:
        u = (float(sample % cam.instants) + 0.5) / float(cam.instants)
    return cam.t0 + u * (cam.t1 - cam.t0)
