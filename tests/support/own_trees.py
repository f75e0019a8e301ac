"""The own-tracer assignment's reference scene and size (tests/server/course/test_own_trees.py and the page's tests of
it)."""

from __future__ import annotations

W, H = 32, 24


# A mirror ball and a red ball over a floor, one point light, max_depth 2: eye, shadow and reflection rays.
REFERENCE = {
    "version": 1,
    "name": "mirror and red",
    "camera": {"lookfrom": [0, 0.5, 5], "lookat": [0, 0, 0], "vfov": 40},
    "film": {"width": W, "height": H},
    "sampler": {"type": "center", "spp": 1},
    "render": {"integrator": "whitted", "max_depth": 2},
    "background": [0.2, 0.3, 0.5],
    "ambient": 0.05,
    "materials": {"red": {"kd": [0.8, 0.1, 0.1], "ks": 0.4, "shininess": 30}, "mirror": {"kd": 0.05, "kr": 0.9},
                  "floor": {"kd": 0.5}},
    "lights": [{"type": "point", "position": [1, 4, 4], "intensity": 40}],
    "objects": [
        {"type": "plane", "name": "floor", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "sphere", "name": "mirror ball", "center": [-0.7, 0, 0], "radius": 0.8, "material": "mirror"},
        {"type": "sphere", "name": "red ball", "center": [1.2, -0.3, 0.5], "radius": 0.6, "material": "red"},
    ],
}  # fmt: skip
