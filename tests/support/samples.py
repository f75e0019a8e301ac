"""Where a camera ray lands on the film, and the tolerance (tests/tracer/test_samples.py and the tests that check
sample positions)."""

from __future__ import annotations

import numpy as np

# film positions recovered from float32 eye-ray directions: a few 1e-5 pixel at these sizes
FILM_TOL = 1e-4


def film_point(cs, node: dict) -> np.ndarray:
    """The film point (fx, fy) a pinhole eye ray passes through (tracer/kernels/camera.py inverted)."""
    cam, d = cs.data.camera, np.asarray(node["direction"], dtype=np.float64)
    forward, right, up = (np.asarray(v, dtype=np.float64) for v in (cam.forward, cam.right, cam.up))
    t = d / d.dot(forward)
    sx, sy = t.dot(right), t.dot(up)
    return np.array(
        [(sx / (cam.h * cam.aspect) + 1.0) * cs.data.width / 2.0, (1.0 - sy / cam.h) * cs.data.height / 2.0]
    )
