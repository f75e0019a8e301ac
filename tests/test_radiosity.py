"""Radiosity: energy bookkeeping, a closed box against its analytic radiosity, and the Cornell box
against the path tracer on the diffuse walls."""

import math

import numpy as np
import pytest
from conftest import scene_dict, small

from tracer.compile import compile_scene
from tracer.radiosity import build_patches, solve
from tracer.raytree import ray_tree
from tracer.render import render
from tracer.scene import load_scene


def closed_box(rho: float, le: float):
    """A closed cube of six quads whose fronts face inwards, each emitting radiance le with kd rho."""
    m = {"kd": rho, "emission": le}
    faces = [
        ([-1, -1, -1], [2, 0, 0], [0, 2, 0]),
        ([-1, -1, 1], [0, 2, 0], [2, 0, 0]),
        ([-1, -1, -1], [0, 2, 0], [0, 0, 2]),
        ([1, -1, -1], [0, 0, 2], [0, 2, 0]),
        ([-1, -1, -1], [0, 0, 2], [2, 0, 0]),
        ([-1, 1, -1], [2, 0, 0], [0, 0, 2]),
    ]
    objects = [{"type": "quad", "corner": c, "edge1": a, "edge2": b, "material": m} for c, a, b in faces]
    return load_scene({"camera": {"lookfrom": [0, 0, 0.5], "lookat": [0, 0, 0]}, "objects": objects})[0]


def test_radiosity_patches_cover_the_surfaces():
    scene, _ = load_scene(scene_dict("cornell_path"))
    cs = compile_scene(scene)
    p = build_patches(cs, 0.5)
    n = len(p) // 2
    # 5 walls of 2x2 -> 16 patches each; two boxes -> 6 faces each; both sides of everything
    walls = p.area[:n][p.obj[:n] < 5].sum()
    assert walls == pytest.approx(5 * 4.0, rel=1e-9)
    assert np.allclose(p.normal[:n], -p.normal[n:]) and np.array_equal(p.twin[p.twin], np.arange(len(p)))
    assert (p.emission[n:] == 0).all()


def test_radiosity_energy_is_conserved():
    scene, _ = load_scene(scene_dict("cornell_path"))
    sol = solve(scene, patch_size=0.5, rays=1024, threshold=0.05)
    balance = sol.emitted - sol.absorbed - sol.unshot.sum(axis=0) - sol.escaped
    np.testing.assert_allclose(balance, 0.0, atol=1e-9 * sol.emitted.max())
    assert (sol.escaped > 0).all()  # the box is open towards the camera
    unshot = [h["unshot"] for h in sol.history]
    assert unshot[-1] <= 0.05 * sol.emitted.sum()
    # the unshot energy only falls once the light has shot
    assert all(b <= a + 1e-12 for a, b in zip(unshot[1:], unshot[2:], strict=False))


def test_radiosity_closed_box_matches_the_analytic_value():
    """Every wall emits E = pi le and reflects rho: B = E / (1 - rho) everywhere, nothing escapes."""
    rho, le = 0.6, 1.0
    sol = solve(closed_box(rho, le), patch_size=0.5, rays=2048, threshold=0.002)
    n = len(sol.patches) // 2
    inner = sol.radiosity[:n]  # every face's front side looks into the box
    expected = math.pi * le / (1 - rho)
    assert inner.mean() == pytest.approx(expected, rel=0.02)
    assert np.abs(inner / expected - 1).max() < 0.1  # per patch: Monte Carlo form factors
    assert np.abs(sol.escaped).max() < 1e-3 * sol.emitted.max()


def test_radiosity_cornell_agrees_with_the_path_tracer_on_the_walls():
    width = 48
    data = small(scene_dict("cornell_path"), width, width, sampler={"type": "jittered", "spp": 256})
    scene, _ = load_scene(data)
    cs = compile_scene(scene)
    sol = solve(cs, patch_size=0.25, rays=4096, threshold=0.01)
    img = render(cs).image
    p, n = sol.patches, len(sol.patches) // 2
    cam = scene.camera
    fwd = np.subtract(cam.lookat, cam.lookfrom)
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, cam.vup)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    h = math.tan(math.radians(cam.vfov) / 2)
    rad, path = [], []
    light = scene.lights[0]
    light_centre = np.add(light.corner, np.add(light.edge1, light.edge2) / 2)
    for k, c in enumerate(p.centres()[:n]):
        if p.obj[k] >= 5:  # the walls only (the blocks' faces are small and mostly hidden)
            continue
        if np.linalg.norm(c - light_centre) < 0.6:  # pixels there also see the light itself
            continue
        v = c - np.asarray(cam.lookfrom)
        x = int((np.dot(v, right) / np.dot(v, fwd) / h + 1) * width / 2)
        y = int((1 - np.dot(v, up) / np.dot(v, fwd) / h) * width / 2)
        if not (0 <= x < width and 0 <= y < width):
            continue
        hit = ray_tree(cs, x, y, 0)["nodes"][0]["hit"]
        if hit is None or hit["object"] != p.obj[k]:  # hidden behind a block, or the light
            continue
        side = k if np.dot(p.normal[k], -v) > 0 else k + n
        rad.append(sol.radiosity[side] / math.pi)
        path.append(img[y, x])
    rad, path = np.array(rad), np.array(path)
    assert len(rad) > 100
    # the walls' mean radiance agrees within 5% (patches are flat, the path tracer is noisy)
    np.testing.assert_allclose(rad.mean(axis=0), path.mean(axis=0), rtol=0.05)


@pytest.mark.parametrize("display", ["two-pass", "flat", "smooth"])
def test_radiosity_integrator_matches_the_path_tracer(display):
    """The radiosity integrator's image (each display mode) has the path tracer's mean within 3%."""
    base = small(scene_dict("cornell_path"), 48, 48, sampler={"type": "jittered", "spp": 16})
    rad = dict(
        base,
        render={
            "integrator": "radiosity",
            "max_depth": 3,
            "light_samples": 4,
            "radiosity": {"display": display, "patch_size": 0.34, "rays": 2048},
        },
    )
    path = small(scene_dict("cornell_path"), 48, 48, sampler={"type": "jittered", "spp": 64})
    a = render(load_scene(rad)[0]).image
    b = render(load_scene(path)[0]).image
    assert a.mean() == pytest.approx(b.mean(), rel=0.03)


def test_radiosity_two_pass_ray_tree_takes_interreflection_from_the_solution():
    data = small(
        scene_dict("cornell_path"),
        32,
        32,
        sampler={"type": "center", "spp": 1},
        render={"integrator": "radiosity", "max_depth": 2, "radiosity": {"patch_size": 0.5, "rays": 1024}},
    )
    cs = compile_scene(load_scene(data)[0])
    img = render(cs).image
    tree = ray_tree(cs, 16, 12)  # the back wall
    eye = tree["nodes"][0]
    assert eye["hit"]["object_name"] == "back wall"
    assert min(eye["terms"]["ambient"]) > 0  # the solution's interreflection, in place of ka Ia
    np.testing.assert_allclose(tree["color"], img[12, 16], rtol=1e-5)
