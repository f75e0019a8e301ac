"""tracer/tools/pixel_samples.py: one pixel's sample positions are the renderer's, checked against its eye rays."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tests.support.samples import FILM_TOL, film_point
from tests.support.scene import scene_dict, small
from tracer.kernels.compile import compile_scene
from tracer.kernels.kinds import RayKind
from tracer.rendering.progressive import Renderer
from tracer.rendering.raytree import ray_tree
from tracer.scene import Sampler, SceneError, load_scene, scene_json_schema
from tracer.tools.pixel_samples import adaptive_count, adaptive_levels, load_kernels, pixel_samples


@pytest.fixture(scope="module", autouse=True)
def kernels():
    load_kernels()


def compiled(sampler: dict, width: int = 37, height: int = 23, **sections):
    scene, _ = load_scene(small(scene_dict("antialias_adaptive"), width, height, sampler=sampler, **sections))
    return compile_scene(scene)


@pytest.mark.parametrize(
    ("sampler", "film"),
    [
        ({"type": "center"}, {}),
        ({"type": "grid", "spp": 9}, {}),
        ({"type": "random", "spp": 7}, {}),
        ({"type": "jittered", "spp": 16}, {}),
        ({"type": "jittered", "spp": 4}, {"filter": {"type": "tent"}}),  # offsets reach into the neighbours
        ({"type": "adaptive", "max_level": 2}, {}),
        ({"type": "adaptive", "max_level": 1, "jitter": True}, {}),
        ({"type": "lowdiscrepancy", "spp": 7}, {}),  # any spp
    ],
    ids=["center", "grid", "random", "jittered", "jittered-tent", "adaptive", "adaptive-jitter", "lowdiscrepancy"],
)
def test_samples_positions_are_the_ray_tree_s_eye_rays(sampler, film):
    cs = compiled(sampler, film={"width": 37, "height": 23, **film}, render={"seed": 5})
    x, y = 21, 9
    listed = pixel_samples(cs, x, y)
    assert listed["pixel"] == [x, y]
    assert listed["sampler"] == sampler["type"]
    for item in listed["samples"]:
        tree = ray_tree(cs, x, y, item["sample"])
        eye = tree["nodes"][0]
        assert eye["kind"] == "eye"
        assert_allclose(film_point(cs, eye), np.add([x, y], item["position"]), atol=FILM_TOL)
        assert item["weight"] == pytest.approx(tree["filter_weight"], abs=1e-6)
    if film:
        offsets = np.array([s["position"] for s in listed["samples"]])
        assert ((offsets < 0) | (offsets > 1)).any(), "a tent filter spreads samples past the pixel's edges"


def test_samples_strata_hold_one_sample_each():
    for kind in ("grid", "jittered"):
        listed = pixel_samples(compiled({"type": kind, "spp": 16}), 3, 4)
        n = listed["strata"]
        assert n == 4
        assert len(listed["samples"]) == 16
        for item in listed["samples"]:
            u, v = item["position"]
            k = item["sample"]
            assert (int(u * n), int(v * n)) == (k % n, k // n)
            if kind == "grid":
                assert (u, v) == ((k % n + 0.5) / n, (k // n + 0.5) / n)
    assert pixel_samples(compiled({"type": "random", "spp": 5}), 0, 0)["strata"] is None


def test_samples_adaptive_grid_levels():
    # level 0: the four corners and the centre of the pixel; each level adds its cells' corners and centres
    g = 8  # max_level 2: a fine grid of 2^3 steps
    levels = adaptive_levels(2)
    assert [k for k, lv in levels.items() if lv == 0] == [0, g, (g // 2) * (g + 1) + g // 2, g * (g + 1), g * (g + 2)]
    assert len(levels) == adaptive_count(2) == 41
    assert max(levels.values()) == 2
    assert 1 * (g + 1) + 2 not in levels  # (2, 1): no cell's corner or centre


def test_samples_adaptive_traces_what_the_renderer_traces():
    """The cells split where the renderer splits them: per pixel, the traced grid points are the eye rays
    of the renderer's last adaptive pass, on a scene with edges, checker and thin poles."""
    cs = compiled({"type": "adaptive", "max_level": 3, "threshold": 0.05}, 24, 18)
    r = Renderer(cs, threads=1)
    r.adaptive_pass(cs.data.max_level)
    eye = r.film.counts.numpy()[..., RayKind.EYE]
    split = 0
    for y in range(cs.data.height):
        for x in range(cs.data.width):
            listed = pixel_samples(cs, x, y)
            traced = [s for s in listed["samples"] if s["traced"]]
            assert len(traced) == eye[y, x], (x, y)
            assert all(s["srgb"] for s in traced)
            assert not any(s["srgb"] for s in listed["samples"] if not s["traced"])
            cells = listed["cells"]
            assert cells[0]["corner"] == [0.0, 0.0]
            assert cells[0]["size"] == 1.0
            assert cells[0]["level"] == 0
            split += sum(c["split"] for c in cells)
    assert split > 20, "the scene has edges: some pixels are subdivided"
    # a uniform pixel: five rays, one cell
    assert eye.min() == 5


def test_samples_limits_and_pixel_off_the_film():
    with pytest.raises(SceneError) as err:
        pixel_samples(compiled({"type": "jittered", "spp": 16}), 37, -1)
    assert [e["path"] for e in err.value.errors] == ["x", "y"]
    with pytest.raises(SceneError) as err:
        pixel_samples(compiled({"type": "random", "spp": 20}), 0, 0, max_samples=16)
    assert err.value.errors == [
        {"path": "sampler.spp", "message": "20 samples per pixel; at most 16 sample positions are listed per pixel"}
    ]
    with pytest.raises(SceneError) as err:
        pixel_samples(compiled({"type": "adaptive", "max_level": 7}), 0, 0)
    assert err.value.errors[0]["path"] == "sampler.max_level"


def test_samples_schema_states_the_spp_default_of_each_sampler():
    spp = scene_json_schema()["$defs"]["Sampler"]["properties"]["spp"]
    by_type = spp["x-default-by-type"]
    kinds = scene_json_schema()["$defs"]["Sampler"]["properties"]["type"]["enum"]
    assert sorted(by_type) == sorted(kinds)
    for kind in kinds:
        assert by_type[kind] == Sampler(type=kind).spp, kind
