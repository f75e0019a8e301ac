"""POST /api/samples: one pixel's sample positions, as the renderer (and POST /api/raytree) uses them."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tests.support.samples import FILM_TOL, film_point
from tests.support.scene import scene_dict, small
from tracer.kernels.compile import compile_scene
from tracer.scene import load_scene

# `client` (tests/conftest.py): the app with a render worker, which traces the ray trees compared with.


def lesson_scene(sampler: dict) -> dict:
    """The Samplers lesson's scene at its size, with this sampler in place of its own."""
    return {**small(scene_dict("antialias_jittered"), 160, 120), "sampler": sampler}


@pytest.mark.parametrize(
    "sampler",
    [{"type": "center"}, {"type": "grid", "spp": 4}, {"type": "jittered", "spp": 16}, {"type": "random", "spp": 3}],
    ids=["center", "grid", "jittered", "random"],
)
def test_api_samples_positions_are_the_ray_tree_s(client, sampler):
    scene = lesson_scene(sampler)
    body = client.post("/api/samples", json={"scene": scene, "x": 70, "y": 64})
    assert body.status_code == 200, body.text
    listed = body.json()
    assert listed["sampler"] == sampler["type"]
    assert listed["filter"] == {"type": "box", "radius": 0.5}
    assert len(listed["samples"]) == sampler.get("spp", 1)
    cs = compile_scene(load_scene(scene)[0])
    for item in listed["samples"]:
        tree = client.post("/api/raytree", json={"scene": scene, "x": 70, "y": 64, "sample": item["sample"]}).json()
        assert_allclose(film_point(cs, tree["nodes"][0]), np.add([70, 64], item["position"]), atol=FILM_TOL)
        assert 0 <= min(item["position"])
        assert max(item["position"]) < 1


def test_api_samples_adaptive_lists_its_grid_levels_and_the_cells_it_split(client):
    scene = small(scene_dict("antialias_adaptive"), 160, 120)
    listed = client.post("/api/samples", json={"scene": scene, "x": 3, "y": 100}).json()
    assert listed["sampler"] == "adaptive"
    assert listed["max_level"] == 3
    assert listed["strata"] is None
    assert len(listed["samples"]) == 145  # (2^3 + 1)^2 corners and 4^3 centres
    assert {s["level"] for s in listed["samples"]} == {0, 1, 2, 3}
    traced = [s for s in listed["samples"] if s["traced"]]
    assert len(traced) >= 5
    assert all(s["srgb"].startswith("#") for s in traced)
    for item in traced[:3]:
        tree = client.post("/api/raytree", json={"scene": scene, "x": 3, "y": 100, "sample": item["sample"]}).json()
        assert tree["sample"] == item["sample"]
        assert tree["nodes"][0]["kind"] == "eye"
    assert listed["cells"][0] == {**listed["cells"][0], "corner": [0.0, 0.0], "size": 1.0, "level": 0}


def test_api_samples_refuses_what_the_scene_and_the_route_refuse(client):
    def errors(scene: dict, x: int = 0, y: int = 0) -> list[dict]:
        r = client.post("/api/samples", json={"scene": scene, "x": x, "y": y})
        assert r.status_code == 422, r.text
        return r.json()["errors"]

    # the scene's own rules: a perfect square for jittered
    assert [e["path"] for e in errors(lesson_scene({"type": "jittered", "spp": 5}))] == ["sampler.spp"]
    # the pixel must lie on the film
    assert [e["path"] for e in errors(lesson_scene({"type": "center"}), 160, -2)] == ["x", "y"]
    # the service's max_spp, for the scene's spp and for the adaptive grid's points
    max_spp = client.app.state.settings.limits.max_spp
    (error,) = errors(lesson_scene({"type": "random", "spp": max_spp + 1}))
    assert error == {"path": "sampler.spp", "message": f"must be at most {max_spp} (limit max_spp)"}
    (error,) = errors(small(scene_dict("antialias_adaptive"), 16, 16, sampler={"max_level": 6}))
    assert error == {
        "path": "sampler.max_level",
        "message": f"max_level 6 has 8321 grid points; at most {max_spp} sample positions are listed per pixel",
    }
    # x and y are integers
    r = client.post("/api/samples", json={"scene": lesson_scene({"type": "center"}), "x": "1", "y": 0})
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "x"


def test_api_samples_is_documented(client):
    paths = client.get("/openapi.json").json()["paths"]
    assert "post" in paths["/api/samples"]
