"""The bug zoo's student tracer (zoo_tracer.py): without bugs it agrees with the renderer on the zoo scene, in
the picture and in the ray trees; each bug switch changes its output where the zoo needs it to.

The renderer computes in float32, the student tracer in float64: they agree to float32 noise, which grows
where rays graze a surface (a silhouette, a far hit near the horizon) and in sharp highlights (cos^150).
"""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from PIL import Image

from tests.owntracer.zoo_tracer import BUGS, ZOO_SCENE, bug_pixels, png_bytes, srgb8, zoo_render, zoo_scene
from tests.owntracer.zoo_trees import tree_difference

# The picture: |student - renderer| <= ABS + REL |renderer| per channel, at all pixels but OUTLIERS of them
IMAGE_ABS = 1e-3
IMAGE_REL = 1e-3
OUTLIERS = 0.005  # a share of the pixels: float32 noise at silhouettes and highlights (1 of 3072 seen)

TIGHT = {"position": 2e-5, "position_rel": 2e-5, "direction": 1e-4}  # the trees' tolerances against the renderer
# A dozen pixels whose trees hold every kind of ray and end: the background; the floor, lit and in the shadow
# of the mirror ball; the mirror ball; the glass ball (through it, inside it, total internal reflection in
# the cube behind it); the mirror seeing the cube; the glass cube (total internal reflection); the red ball.
TREE_PIXELS = [
    (0, 0),
    (5, 40),
    (13, 23),
    (25, 16),
    (38, 18),
    (30, 25),
    (23, 21),
    (10, 26),
    (18, 27),
    (49, 20),
    (36, 15),
    (40, 30),
]


@pytest.fixture(scope="module")
def reference(compiled_kernels):
    """The zoo scene compiled for the renderer."""
    from tracer.kernels.compile import compile_scene
    from tracer.scene import load_scene

    scene, warnings = load_scene(zoo_scene())
    assert warnings == []
    return compile_scene(scene)


def test_zoo_tracer_scene_is_valid_and_centre_sampled():
    from tracer.__main__ import main

    assert main(["validate", str(ZOO_SCENE)]) == 0
    data = zoo_scene()
    assert data["sampler"] == {"type": "center", "spp": 1}
    assert data["render"]["integrator"] == "whitted"
    assert [light["type"] for light in data["lights"]] == ["point", "point"]
    assert {o["type"] for o in data["objects"]} == {"plane", "sphere", "quad"}


def test_zoo_tracer_image_equals_the_renderers(reference):
    from tracer.rendering.film import to_srgb8
    from tracer.rendering.progressive import render

    ref = render(reference, threads=1).image.astype(np.float64)
    image, trees, picture = zoo_render(None)
    assert image.shape == ref.shape == (48, 64, 3)
    off = (np.abs(image - ref) > IMAGE_ABS + IMAGE_REL * np.abs(ref)).any(axis=2)
    assert off.sum() <= OUTLIERS * off.size, f"{off.sum()} pixels differ: {np.argwhere(off)[:10, ::-1].tolist()}"
    # each tree's colour is its pixel, and the 8-bit picture is the renderer's PNG (one level of rounding)
    assert all(np.array_equal(image[y, x], tree["color"]) for (x, y), tree in trees.items())
    levels = np.abs(picture.astype(int) - to_srgb8(ref).astype(int)).max(axis=2)
    assert (levels > 1).sum() <= OUTLIERS * levels.size
    assert np.array_equal(picture, srgb8(image))
    assert np.array_equal(srgb8(image, 1.5), to_srgb8(image, 1.5)), "exposure: 2^1.5 before the clamp"
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(png_bytes(image)))), picture)


def test_zoo_tracer_trees_equal_the_renderers(reference):
    """Node by node at a dozen pixels: the same rays, hits, normals, weights, terms and radiance, within float32
    noise: 2e-5 world units + 2e-5 of the size for origins, points and t (tight enough to see the 1e-4 offset
    of a spawned ray), 1e-4 for unit vectors, 1e-3 relative + 1e-5 for colours (a highlight's cos^150)."""
    from tracer.rendering.raytree import ray_tree

    _, trees, _ = zoo_render(None)
    ends = set()
    for x, y in TREE_PIXELS:
        ref = ray_tree(reference, x, y)
        assert tree_difference(ref, trees[x, y], **TIGHT) is None, (x, y)
        assert len(ref["nodes"]) == len(trees[x, y]["nodes"])
        assert math.isclose(ref["color"][0], trees[x, y]["color"][0], rel_tol=1e-3, abs_tol=1e-5)
        ends |= {n["end"] for n in ref["nodes"]}
        ends |= {"occluded" for n in ref["nodes"] if n["occluded"]}
    assert {"miss", "light", "occluded", "absorbed", "tir", "max_depth"} <= ends, "the pixels cover every end"


def test_zoo_tracer_trees_differ_from_the_renderers_when_they_should(reference):
    """The yardstick sees a bug: the renderer's tree and the student's under `reflection_sign` differ."""
    from tracer.rendering.raytree import ray_tree

    _, bad, _ = zoo_render("reflection_sign")
    why = tree_difference(ray_tree(reference, 25, 16), bad[25, 16])
    assert why is not None
    assert why.startswith("eye > reflection")


@pytest.mark.parametrize("bug", BUGS)
def test_zoo_tracer_bug_changes_the_output(bug):
    """Every bug shows at 3 pixels or more of the zoo scene (many more, in fact), so the zoo can name it."""
    pixels = bug_pixels(bug)
    assert len(pixels) >= 3 * 10, f"{bug} shows at {len(pixels)} pixels only"


def _depth(nodes: list[dict], node: dict | None) -> int:
    """The scene format's depth of a node: the eye ray 1, its reflection 2, a shadow ray its parent's."""
    depth = 0
    while node is not None:
        depth += node["kind"] != "shadow"
        node = None if node["parent"] is None else nodes[node["parent"]]
    return depth


def _shown(bug: str, test) -> list[tuple[int, int]]:
    """The pixels where `bug` shows and test(correct tree, buggy tree) holds."""
    _, good, _ = zoo_render(None)
    _, bad, _ = zoo_render(bug)
    return [p for p in bug_pixels(bug) if test(good[p], bad[p])]


def test_zoo_tracer_bugs_show_as_their_names_say():
    """Each bug changes what its name says, at 3 pixels or more (the rest of its tree may differ too)."""

    def acne(good, bad):  # a shadow ray blocked by its own surface right at its start
        surface = {n["id"]: (n["hit"] or {}).get("object") for n in bad["nodes"]}
        return any(
            n["kind"] == "shadow" and n["occluded"] and n["t"] < 1e-3 and n["hit"]["object"] == surface[n["parent"]]
            for n in bad["nodes"]
        )

    def normal_along_the_ray(good, bad):  # a hit normal not turned towards the ray
        return any(n["hit"] and np.dot(n["hit"]["normal"], n["direction"]) > 0 for n in bad["nodes"])

    def rays(kind):
        return lambda tree: sum(n["kind"] == kind for n in tree["nodes"])

    def deeper(good, bad):
        return max(_depth(bad["nodes"], n) for n in bad["nodes"]) > zoo_scene()["render"]["max_depth"]

    def eye_direction(good, bad):
        return tree_difference({"nodes": good["nodes"][:1]}, {"nodes": bad["nodes"][:1]}) is not None

    def same_tree(good, bad):
        return tree_difference(good, bad) is None

    checks = {
        "shadow_acne": acne,
        "flipped_normal": normal_along_the_ray,
        "no_tir": lambda good, bad: rays("transmission")(bad) > rays("transmission")(good),
        "depth_off_by_one": deeper,
        "half_pixel": eye_direction,
        "vfov_horizontal": eye_direction,
        "no_srgb": same_tree,  # the trees are right, only the picture is wrong
    }
    for bug, test in checks.items():
        assert len(_shown(bug, test)) >= 3, bug
    _, good, _ = zoo_render(None)
    _, bad, _ = zoo_render("no_srgb")
    assert all(tree_difference(good[p], bad[p]) is None for p in good), "no_srgb leaves every tree as it is"
