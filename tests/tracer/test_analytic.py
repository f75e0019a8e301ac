"""Whitted renders of scenes whose answer is known in closed form (docs/scene-format.md semantics).

Tolerances: radiance is computed in float32 along the whole path, so agreement is to ~1e-5
relative; positions of hits to ~1e-4 (the 1e-4 spawn offset is part of the contract).
"""

import math

import numpy as np
from numpy.testing import assert_allclose

from tracer.rendering.progressive import render
from tracer.rendering.raytree import ray_tree
from tracer.scene import load_scene


def base(objects, lights=(), materials=None, **extra):
    d = {
        "camera": {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0], "vfov": 40},
        "film": {"width": 16, "height": 12},
        "sampler": {"type": "center"},
        "render": {"max_depth": 5, "min_weight": 0},
        "materials": materials or {},
        "lights": list(lights),
        "objects": list(objects),
    }
    d.update(extra)
    return load_scene(d)[0]


def camera_dir(scene, x, y):
    """The spec's camera ray for the centre of pixel (x, y), in float64."""
    c, f = scene.camera, scene.film
    fwd = np.subtract(c.lookat, c.lookfrom)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, c.vup)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    h = math.tan(math.radians(c.vfov) / 2)
    d = fwd + (2 * (x + 0.5) / f.width - 1) * h * (f.width / f.height) * right + (1 - 2 * (y + 0.5) / f.height) * h * up
    return d / np.linalg.norm(d)


def test_analytic_point_light_over_lambertian_plane():
    kd, intensity = 0.6, 4.0
    s = base(
        [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": {"kd": kd}}],
        [{"type": "point", "position": [0.3, 2, -0.5], "intensity": intensity}],
        camera={"lookfrom": [0, 5, 0.01], "lookat": [0, 0, 0], "vup": [0, 0, -1], "vfov": 60},
    )
    img = render(s, threads=1).image
    for x, y in [(0, 0), (8, 6), (15, 11), (3, 9)]:
        d = camera_dir(s, x, y)
        o = np.array(s.camera.lookfrom)
        p = o + (-o[1] / d[1]) * d
        to_l = np.array([0.3, 2, -0.5]) - p
        dist = np.linalg.norm(to_l)
        expected = kd / math.pi * intensity * (to_l[1] / dist) / dist**2
        assert_allclose(img[y, x], expected, rtol=2e-5)


def test_analytic_directional_light_and_ambient():
    s = base(
        [
            {
                "type": "quad",
                "corner": [-5, -5, 0],
                "edge1": [10, 0, 0],
                "edge2": [0, 10, 0],
                "material": {"kd": [0.5, 0.25, 1.0], "ka": 0.2},
            }
        ],
        [{"type": "directional", "direction": [0, -1, -1], "irradiance": 2.0}],
        ambient=0.5,
    )
    img = render(s, threads=1).image
    expected = 0.2 * 0.5 + np.array([0.5, 0.25, 1.0]) / math.pi * 2.0 * math.cos(math.radians(45))
    assert_allclose(img[6, 8], expected, rtol=1e-5)


def test_analytic_mirror_reflects_background_with_weight_kr():
    objects = [
        {
            "type": "quad",
            "corner": [-5, -5, 0],
            "edge1": [10, 0, 0],
            "edge2": [0, 10, 0],
            "material": {"kd": 0, "kr": 0.8},
        }
    ]
    s = base(objects, background=[0.5, 0.25, 1.0])
    img = render(s, threads=1).image
    assert_allclose(img, np.broadcast_to([0.4, 0.2, 0.8], img.shape), rtol=1e-6)
    tree = ray_tree(s, 8, 6)
    eye, refl = tree["nodes"]
    assert (eye["kind"], eye["end"], refl["kind"], refl["end"]) == ("eye", None, "reflection", "miss")
    assert_allclose(refl["direction"], [0, 0, 1], atol=0.2)
    assert_allclose(refl["weight"], [0.8] * 3)
    # ray casting: the reflection ray is wanted but depth 2 > max_depth 1
    s1 = base(objects, background=[0.5, 0.25, 1.0], render={"max_depth": 1})
    assert_allclose(render(s1, threads=1).image[6, 8], 0)
    assert ray_tree(s1, 8, 6)["nodes"][0]["end"] == "max_depth"


def test_analytic_glass_slab_refraction():
    """A slab of glass (kt = 1, no Fresnel) bends rays by Snell's law and lets them out parallel."""
    s = base(
        [{"type": "box", "min": [-20, -20, -0.5], "max": [20, 20, 0.5], "material": {"kd": 0, "kt": 1, "ior": 1.5}}],
        background=[0.3, 0.6, 0.9],
        camera={"lookfrom": [0, 0, 5], "lookat": [3, 0, 0], "vfov": 30},
    )
    img = render(s, threads=1).image
    assert_allclose(img, np.broadcast_to([0.3, 0.6, 0.9], img.shape), rtol=1e-5)  # no loss through the slab
    tree = ray_tree(s, 8, 6)
    eye, inside, out = tree["nodes"]
    assert [n["kind"] for n in (eye, inside, out)] == ["eye", "transmission", "transmission"]
    assert (inside["parent"], out["parent"], out["end"]) == (0, 1, "miss")
    d_in, d_t = np.array(eye["direction"]), np.array(inside["direction"])
    sin_i = math.hypot(d_in[0], d_in[1])
    assert_allclose(math.hypot(d_t[0], d_t[1]), sin_i / 1.5, rtol=1e-5)  # Snell
    assert_allclose(out["direction"], d_in, atol=1e-6)  # leaves parallel to the eye ray
    # the spawned ray starts 1e-4 behind the surface it crossed
    assert_allclose(inside["origin"][2], 0.5 - 1e-4, atol=1e-6)
    assert eye["hit"]["front_face"]
    assert not inside["hit"]["front_face"]


def test_analytic_fresnel_weights_at_normal_incidence():
    s = base(
        [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "glass"}],
        materials={"glass": {"kd": 0, "kr": 1, "kt": 1, "ior": 1.5, "fresnel": True}},
        film={"width": 15, "height": 15},
    )
    nodes = ray_tree(s, 7, 7)["nodes"]
    eye = nodes[0]
    kids = {n["kind"]: n for n in nodes if n["parent"] == 0}
    assert_allclose(kids["reflection"]["k"], [0.04] * 3, rtol=1e-3)
    assert_allclose(kids["transmission"]["k"], [0.96] * 3, rtol=1e-4)
    assert eye["end"] is None


def test_analytic_total_internal_reflection_in_a_glass_cube():
    """Looking into a cube at 45 degrees, refracted rays meet a side face past the critical angle."""
    s = base(
        [
            {
                "type": "box",
                "min": [-1, -1, -1],
                "max": [1, 1, 1],
                "material": {"kd": 0, "kr": 0.5, "kt": 0.5, "ior": 1.5},
            }
        ],
        camera={"lookfrom": [-4, 0, 4], "lookat": [0, 0, 0], "vfov": 30},
        film={"width": 24, "height": 8},
        render={"max_depth": 4, "min_weight": 0},
    )
    found = 0
    for x in range(24):
        nodes = ray_tree(s, x, 4)["nodes"]
        for n in nodes:
            if n["end"] == "tir":
                kids = [c for c in nodes if c["parent"] == n["id"] and c["kind"] != "shadow"]
                assert [c["kind"] for c in kids] == ["reflection"]
                # without Fresnel the transmission ray's weight goes to the reflection ray: kr + kt
                assert_allclose(kids[0]["k"], [1.0] * 3)
                assert n["hit"]["front_face"] is False
                found += 1
    assert found > 0


def test_analytic_fog_mixes_with_distance():
    s = base(
        [
            {
                "type": "quad",
                "corner": [-50, -50, -3],
                "edge1": [100, 0, 0],
                "edge2": [0, 100, 0],
                "material": {"kd": 0, "emission": 1.0},
            }
        ],
        fog={"density": 0.2, "color": [0.2, 0.4, 0.6]},
    )
    img = render(s, threads=1).image
    d = camera_dir(s, 8, 6)
    t = 8 / -d[2]  # from z = 5 to the wall at z = -3
    a = math.exp(-0.2 * t)
    assert_allclose(img[6, 8], a * 1.0 + (1 - a) * np.array([0.2, 0.4, 0.6]), rtol=1e-5)
    # a ray that leaves the scene returns the fog colour
    s2 = base([], fog={"density": 0.2, "color": [0.2, 0.4, 0.6]}, background=1.0)
    assert_allclose(render(s2, threads=1).image[0, 0], [0.2, 0.4, 0.6], rtol=1e-6)


def test_analytic_shadow_and_spot_cone():
    plane = {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": {"kd": 0.5}}
    cam = {"lookfrom": [0, 6, 0.01], "lookat": [0, 0, 0], "vup": [0, 0, -1], "vfov": 40}
    plane_only = base(
        [plane, {"type": "sphere", "center": [0, -0.5, 0], "radius": 0.3, "material": {"kd": 0.5}}],
        [{"type": "point", "position": [0, 3, 3], "intensity": 5}],
        ambient=0.1,
        camera=cam,
    )
    # the shadow of the small sphere falls towards -z (up in the image)
    shadows = [ray_tree(plane_only, 8, y) for y in range(0, 6)]
    occluded = [t for t in shadows if t["nodes"][0]["hit"]["object"] == 0 and t["nodes"][1]["occluded"]]
    assert occluded, "expected a pixel of the plane in the sphere's shadow"
    t = occluded[0]
    assert_allclose(t["color"], [0.05] * 3, rtol=1e-5)  # ka = kd = 0.5 times ambient 0.1
    assert t["nodes"][1]["end"] == "absorbed"
    assert t["nodes"][1]["hit"]["object"] == 1
    # a spot light pointing away casts no shadow ray at all
    spot = base(
        [plane],
        [{"type": "spot", "position": [0, 3, 0], "direction": [0, 1, 0], "intensity": 5, "cutoff": 30}],
        camera=cam,
    )
    assert [n["kind"] for n in ray_tree(spot, 8, 6)["nodes"]] == ["eye"]
    # inside the cone: L = f_att I cos(psi)^falloff cos(theta) kd / pi straight below the light
    spot2 = base(
        [plane],
        [{"type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0], "intensity": 5, "cutoff": 30, "falloff": 2}],
        camera={**cam, "lookfrom": [0, 6, 0.0001]},
        film={"width": 1, "height": 1},
    )
    assert_allclose(render(spot2, threads=1).image[0, 0], 5 / 16 * 0.5 / math.pi, rtol=1e-4)
