"""whitted_simple.py, Whitted in lecture size, against whitted.py, the full integrator (STYLE.md item 7): the
same images, bit for bit, with the same rays and AOVs, on every example scene it covers (the `whitted`
integrator without fog; the radiosity integrator's scenes and fog.json are whitted.py's alone) and on small
scenes of its own: a mirror, glass with Fresnel and total internal reflection, with and without it, area
lights with light_samples and their shadows, a glossy mirror.

Bit for bit, not within a tolerance: without fog or a radiosity solution whitted.py adds the same terms in
the same order (fog_t = 1 and shown = 0 multiply exactly), traces the rays in the same order and draws the
same random numbers."""

import numpy as np
import pytest

from tests.support.scene import EXAMPLES, scene_dict, small
from tracer.integrators import dispatch, whitted_simple
from tracer.kernels.compile import compile_scene
from tracer.rendering.progressive import Renderer
from tracer.rendering.raytree import ray_tree
from tracer.scene import load_scene

SIMPLE = dispatch.make_kernels(whitted_simple.trace, "tracer_kernels_whitted_simple")  # beside KERNELS, unlisted

WALLS = {"kd": [0.7, 0.7, 0.7], "ks": 0.2, "shininess": 16}
OWN = {  # small scenes of its own: what the lecture's Shade() does, each at least once
    "mirror_and_glass": {
        "camera": {"lookfrom": [0, 1.5, 5], "lookat": [0, 0.6, 0], "vfov": 45},
        "render": {"integrator": "whitted", "max_depth": 6, "min_weight": 0.01},
        "ambient": [0.1, 0.1, 0.1],
        "background": [0.2, 0.3, 0.5],
        "materials": {
            "floor": WALLS,
            "mirror": {"kd": 0.05, "ks": 0.5, "shininess": 200, "kr": 0.9},
            "fresnel_glass": {"kd": 0, "ks": 0.5, "shininess": 200, "kr": 1, "kt": 1, "ior": 1.5, "fresnel": True},
            # a prism of glass without Fresnel: rays inside meet its faces past the critical angle (kt goes to kr)
            "plain_glass": {"kd": 0, "ks": 0, "kr": 0.1, "kt": 0.9, "ior": 1.7},
        },
        "lights": [{"type": "point", "position": [2, 4, 3], "intensity": 40}],
        "objects": [
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "quad", "corner": [-2.5, 0, -1.5], "edge1": [5, 0, 0], "edge2": [0, 2.5, 0], "material": "mirror"},
            {"type": "sphere", "center": [-0.9, 0.6, 0.5], "radius": 0.6, "material": "fresnel_glass"},
            {"type": "box", "min": [0.3, 0.0, 0.0], "max": [1.5, 1.2, 1.2], "material": "fresnel_glass"},
            {
                "type": "triangle",
                "vertices": [[-0.3, 0.2, 1.6], [0.6, 0.2, 1.6], [0.15, 1.4, 1.3]],
                "material": "plain_glass",
            },
            {"type": "box", "min": [-0.4, 1.3, 0.9], "max": [0.7, 1.6, 1.8], "material": "plain_glass"},
        ],
    },
    "area_lights_and_gloss": {
        "camera": {"lookfrom": [0, 2, 5], "lookat": [0, 0.5, 0], "vfov": 50},
        "render": {"integrator": "whitted", "max_depth": 4, "light_samples": 4},
        "ambient": [0.05, 0.05, 0.05],
        "materials": {
            "floor": WALLS,
            "brushed": {"kd": 0.1, "ks": 0.3, "shininess": 50, "kr": 0.8, "gloss": 200},
            "glass": {"kd": 0, "ks": 0, "kr": 1, "kt": 1, "ior": 1.5, "fresnel": True},
        },
        "lights": [
            {"type": "quad", "corner": [-1, 3, -1], "edge1": [2, 0, 0], "edge2": [0, 0, 2], "radiance": 6},
            {"type": "sphere", "center": [2, 2, 1], "radius": 0.3, "radiance": 8},
        ],
        "objects": [
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "sphere", "center": [-0.8, 0.6, 0], "radius": 0.6, "material": "brushed"},
            {"type": "sphere", "center": [0.8, 0.6, 0.3], "radius": 0.6, "material": "glass"},
        ],
    },
}


def covered(path) -> bool:
    """An example whitted_simple renders: the whitted integrator, no fog."""
    scene, _ = load_scene(path)
    return scene.render.integrator == "whitted" and scene.fog.density == 0


COVERED = [p for p in EXAMPLES if covered(p)]


def render_both(data: dict) -> tuple[Renderer, Renderer]:
    """The scene rendered by whitted.py (the table's kernels) and by whitted_simple.py (SIMPLE)."""
    scene, _ = load_scene(data)
    cs = compile_scene(scene)
    full, simple = Renderer(cs, threads=1), Renderer(cs, threads=1)
    simple.render_pixels, simple.render_adaptive = SIMPLE[:2]
    for r in (full, simple):
        if r.adaptive:
            for level in range(cs.data.max_level + 1):
                r.adaptive_pass(level)
        else:
            r.add_samples(0, r.spp)
    return full, simple


def assert_same(full: Renderer, simple: Renderer) -> None:
    assert full.image().mean() > 0.01, "a black image proves nothing"
    assert np.array_equal(simple.image(), full.image()), np.abs(simple.image() - full.image()).max()
    assert simple.rays() == full.rays()
    a, b = simple.aovs(), full.aovs()
    assert all(np.array_equal(a[k], b[k]) for k in a)


def test_whitted_simple_covers_the_whitted_examples():
    names = {p.stem for p in COVERED}
    assert {"whitted", "cornell", "cornell_whitted_area", "soft_shadows", "phong", "glossy", "etched_glass"} <= names
    assert {"fog", "cornell_path", "cornell_radiosity"}.isdisjoint(names)


@pytest.mark.parametrize("path", COVERED, ids=[p.stem for p in COVERED])
def test_whitted_simple_renders_every_covered_example_as_whitted_does(path):
    """Bit for bit, with the scene's own sampler (jittered, adaptive, lens, shutter) at a small size."""
    data = small(scene_dict(path.stem), 24, 18)
    if data.get("sampler", {}).get("spp", 1) > 4:
        data["sampler"]["spp"] = 4  # a perfect square, for the grid sampler
    assert_same(*render_both(data))


@pytest.mark.parametrize("name", sorted(OWN))
def test_whitted_simple_renders_its_own_scenes_as_whitted_does(name):
    assert_same(*render_both(small(OWN[name], 40, 30, sampler={"type": "jittered", "spp": 4})))


def test_whitted_simple_the_own_scenes_have_what_they_test():
    """The mirror-and-glass scene's trees (whitted.py's, recorded) have total internal reflection in both
    glasses, with Fresnel and without, as well as reflection off the mirror and shadow rays."""
    scene, _ = load_scene(small(OWN["mirror_and_glass"], 40, 30, sampler={"type": "center", "spp": 1}))
    cs = compile_scene(scene)
    nodes = [n for y in range(0, 30, 3) for x in range(0, 40, 3) for n in ray_tree(cs, x, y)["nodes"]]
    tir = {n["hit"]["material"] for n in nodes if n["end"] == "tir"}
    assert tir == {"fresnel_glass", "plain_glass"}, tir
    assert any(n["kind"] == "reflection" and n["hit"] and n["hit"]["material"] == "mirror" for n in nodes)
    assert any(n["kind"] == "shadow" for n in nodes)
