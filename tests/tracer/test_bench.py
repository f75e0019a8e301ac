"""The benchmark's comparison with Mitsuba 3 (tracer/tools/bench_mitsuba.py): the scene it writes for Mitsuba,
our renderer timed as a whole process, and the samples our renderer needs to reach a given RMSE.
Mitsuba itself is an optional dependency of the benchmark, never of the tests: nothing here runs it."""

import json
import math

import numpy as np
import pytest

from tests.support.scene import SCENES
from tracer.scene import load_scene
from tracer.tools import bench_mitsuba
from tracer.tools.bench import cornell_data


def test_bench_spp_to_reach_interpolates_on_log_log_axes():
    curve = [(s, 1 / math.sqrt(s)) for s in (1, 2, 4, 8, 16, 32, 64)]
    assert bench_mitsuba.spp_to_reach(curve, 1 / math.sqrt(40)) == pytest.approx(40)
    assert bench_mitsuba.spp_to_reach(curve, 1 / math.sqrt(64)) == pytest.approx(64)
    # past the last pass: extrapolated along the last two
    assert bench_mitsuba.spp_to_reach(curve, 1 / math.sqrt(256)) == pytest.approx(256)
    # a curve that falls faster than 1/sqrt(spp) (better sampling) needs fewer samples
    fast = [(s, 1 / s) for s in (1, 2, 4, 8, 16, 32, 64)]
    assert bench_mitsuba.spp_to_reach(fast, 1 / 40) == pytest.approx(40)
    assert bench_mitsuba.spp_to_reach([(64, 0.1)], 0.05) is None


def test_bench_mitsuba_scene_is_json_with_the_same_settings(tmp_path):
    """The Cornell box for Mitsuba: plain JSON (a look-at for the camera), path segments = our bounces + 1,
    our random sampler as Mitsuba's independent one, every quad and box face as OBJ quads."""
    scene, _ = load_scene(cornell_data(32, 16))
    spec = bench_mitsuba.write_spec(scene, 16, tmp_path)
    d = json.loads(spec.read_text())
    assert d["integrator"] == {"type": "path", "max_depth": 8}
    assert d["sensor"]["sampler"] == {"type": "independent", "sample_count": 16}
    assert d["sensor"]["look_at"] == {"origin": [0, 0, 3.9], "target": [0, 0, 0], "up": [0, 1, 0]}
    assert d["sensor"]["film"]["width"] == 32
    assert d["sensor"]["film"]["rfilter"] == {"type": "box"}
    objs = [(tmp_path / f"obj{i}.obj").read_text().splitlines() for i in range(7)]
    faces = [sum(line.startswith("f ") for line in lines) for lines in objs]
    assert faces == [2, 2, 2, 2, 2, 12, 12]  # five walls, two boxes: two triangles a quad
    assert d["light0"]["emitter"]["radiance"]["value"] == [17.0, 17.0, 17.0]
    jittered = json.loads((SCENES / "cornell_path.json").read_text())
    s2, _ = load_scene(jittered)
    assert bench_mitsuba.scene_dict(s2, 64, tmp_path)["sensor"]["sampler"]["type"] == "stratified"
    jittered["sampler"] = {"type": "lowdiscrepancy", "spp": 64}
    s3, _ = load_scene(jittered)
    assert bench_mitsuba.scene_dict(s3, 64, tmp_path)["sensor"]["sampler"]["type"] == "ldsampler"


def test_bench_interior_leaves_out_the_light_and_its_rim():
    """RMSE 'inside': the pixels more than 3 steps (up, down, left, right) from any whose reference radiance
    passes 1.5 (the light)."""
    ref = np.full((20, 30, 3), 0.5)
    ref[5:7, 10:14] = 17.0
    inside = bench_mitsuba.interior(ref)
    y, x = np.mgrid[:20, :30]
    steps = np.maximum(0, np.maximum(5 - y, y - 6)) + np.maximum(0, np.maximum(10 - x, x - 13))
    assert np.array_equal(inside, steps > 3)
    img = ref.copy()
    img[6, 12] += 1.0  # an error on the light: the whole image's RMSE, not the inside's
    img[15, 25] += 0.3
    assert bench_mitsuba.rmse(img, ref, inside) == pytest.approx(math.sqrt(0.3**2 / inside.sum()))
    assert bench_mitsuba.rmse(img, ref) == pytest.approx(math.sqrt((1.0 + 0.3**2) / 600))


def test_bench_mitsuba_scene_names_what_it_cannot_convert(tmp_path):
    data = cornell_data(32, 16)
    data["objects"].append({"type": "sphere", "center": [0, 0, 0], "radius": 0.2, "material": "white"})
    scene, _ = load_scene(data)
    with pytest.raises(ValueError, match=r"objects\[7\]: only quads and boxes"):
        bench_mitsuba.scene_dict(scene, 16, tmp_path)


def test_bench_times_our_renderer_as_a_whole_process(tmp_path):
    """`python -m tracer render` in a process of its own: its wall and CPU time, the render's seconds
    from its last line, and its image from the EXR, the same as rendering in this process."""
    from tracer.rendering.progressive import render

    data = cornell_data(16, 4)
    scene_file = tmp_path / "scene.json"
    scene_file.write_text(json.dumps(data))
    r = bench_mitsuba.run_ours(scene_file, tmp_path / "ours", threads=1)
    assert r["wall"] > r["render_s"] > 0
    assert r["cpu"] > 0
    assert r["image"].shape == (16, 16, 3)
    np.testing.assert_array_equal(r["image"], render(load_scene(data)[0], threads=1).image)
