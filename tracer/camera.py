"""Primary rays: the pinhole camera of SCENE_FORMAT.md ("Camera ray").

direction = normalize(forward + (2(x+u)/width - 1) h aspect right + (1 - 2(y+v)/height) h up),
with h = tan(vfov / 2); pixel (x, y) counts columns from the left and rows from the top.
"""

import warp as wp

from tracer.compile import CameraData


@wp.func
def camera_ray(cam: CameraData, fx: float, fy: float, width: int, height: int):
    """Origin and unit direction of the ray through film position (fx, fy) = (x + u, y + v)."""
    sx = (2.0 * fx / float(width) - 1.0) * cam.h * cam.aspect
    sy = (1.0 - 2.0 * fy / float(height)) * cam.h
    d = wp.normalize(cam.forward + sx * cam.right + sy * cam.up)
    return cam.origin, d
