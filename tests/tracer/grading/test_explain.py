"""A student tracer's tree log against the reference's trees (tracer/grading/explain.py, treelog.py, probes.py):
the reference's own trees, logged with the contract's fields only, match at every pixel tried; each classic bug,
made by hand in one node of a right log, is named by its `what` with a message that says what to fix; a log's
errors come all at once at their paths; probes are one per region of the error map; and the reference's tree
at a pixel is the kernels' own (its colour is the pixel of a centre-sampled render, bit for bit).

The scene (own_tracer_scene.json) has a glass ball, a glass block (total internal reflection at its sides), a
mirror, a red ball with a highlight, a floor and two point lights with inverse-square fall-off."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tracer.grading import probes, treelog
from tracer.grading.explain import WHATS, Explainer

SCENE = json.loads((Path(__file__).parent / "own_tracer_scene.json").read_text())


def logged(tree: dict) -> dict:
    """The reference's tree as a right tracer logs it: the contract's fields only (no depth, end, material...)."""
    return copy.deepcopy(treelog.as_logged(tree))


@pytest.fixture(scope="module")
def ex():
    return Explainer(SCENE)


@pytest.fixture(scope="module")
def places(ex) -> dict[str, list[tuple[int, int]]]:
    """Pixels (a grid of every third one) by what their reference trees have there."""
    out: dict[str, list[tuple[int, int]]] = {}
    for y in range(1, ex.height, 3):
        for x in range(1, ex.width, 3):
            tree = ex.reference_tree(x, y)
            for n in tree["nodes"]:
                keys = [n["kind"], n["end"] or ""]
                if n["kind"] == "shadow" and not n["occluded"]:
                    keys.append("lit")
                if n["hit"] and not n["hit"]["front_face"]:
                    keys.append("inside")
                if n["kind"] == "transmission" and n["hit"] and n["hit"]["front_face"]:
                    keys.append("entering")
                for k in keys:
                    if (x, y) not in out.setdefault(k, []):
                        out[k].append((x, y))
    return out


def first(ex, log_tree: dict, image=None) -> dict:
    (answer,) = ex.compare({"trees": [log_tree]}, image)
    assert not answer["matches"], "the changed log matched the reference"
    return answer["differences"][0]


def node_where(tree: dict, test) -> dict:
    return next(n for n in tree["nodes"] if test(n))


def drop(tree: dict, node_id: int) -> None:
    """Remove a node and everything below it."""
    gone = {node_id}
    for n in sorted(tree["nodes"], key=lambda n: n["id"]):
        if n["parent"] in gone:
            gone.add(n["id"])
    tree["nodes"] = [n for n in tree["nodes"] if n["id"] not in gone]


def test_explain_the_reference_logged_as_a_tracer_would_matches_everywhere(ex, places):
    pixels = sorted({p for ps in places.values() for p in ps[:4]})
    assert len(pixels) >= 12
    answers = ex.compare({"trees": [logged(ex.reference_tree(x, y)) for x, y in pixels]})
    wrong = [(a["pixel"], a["differences"][:1]) for a in answers if not a["matches"]]
    assert not wrong, wrong


def test_explain_the_reference_tree_is_the_kernels_own_pixel(ex):
    """The tree's colour is the pixel of the centre-sampled image, rendered by the same kernels (bit for bit)."""
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.progressive import render

    image = render(compile_scene(ex.scene)).image
    for x, y in ((5, 5), (20, 30), (45, 25), (60, 40)):
        assert ex.reference_tree(x, y)["color"] == [float(c) for c in image[y, x]], (x, y)


def test_explain_an_eye_ray_through_the_corner_or_with_vfov_as_horizontal(ex):
    x, y = 50, 10
    tree = logged(ex.reference_tree(x, y))
    forward, right, up, h, aspect = ex.camera_frame()
    corner = forward + (2 * x / ex.width - 1) * h * aspect * right + (1 - 2 * y / ex.height) * h * up
    tree["nodes"][0]["direction"] = list(corner)
    d = first(ex, tree)
    assert d["what"] == "eye_ray" and "corner" in d["message"], d
    hh = h / aspect  # vfov taken as the horizontal angle: tan(vfov/2) spans the width
    wide = forward + (2 * (x + 0.5) / ex.width - 1) * hh * aspect * right + (1 - 2 * (y + 0.5) / ex.height) * hh * up
    tree["nodes"][0]["direction"] = list(wide)
    d = first(ex, tree)
    assert d["what"] == "eye_ray" and "VERTICAL" in d["message"], d


def test_explain_shadow_acne_and_a_wrong_shadow(ex, places):
    x, y = places["lit"][0]
    tree = logged(ex.reference_tree(x, y))
    s = node_where(tree, lambda n: n["kind"] == "shadow" and not n["occluded"])
    parent = next(n for n in tree["nodes"] if n["id"] == s["parent"])
    s.update(occluded=True, t=2e-6, hit={"point": parent["hit"]["point"], "object": parent["hit"]["object"]})
    d = first(ex, tree)
    assert d["what"] == "shadow_acne" and d["student"] == s["id"], d
    assert "offset" in d["message"].lower() and "t = 2e-06" in d["message"], d["message"]
    other = (parent["hit"]["object"] + 1) % len(SCENE["objects"])
    s.update(t=0.5, hit={"object": other})
    d = first(ex, tree)
    assert d["what"] == "shadow" and "blocked" in d["message"], d


def test_explain_a_missing_distance_attenuation_and_a_wrong_highlight(ex, places):
    def d2(n: dict, tree: dict) -> float:  # the squared distance from the ray's parent's hit to its light
        parent = next(m for m in tree["nodes"] if m["id"] == n["parent"])
        position = SCENE["lights"][n["light"]]["position"]
        return sum((a - b) ** 2 for a, b in zip(position, parent["hit"]["point"], strict=True))

    # a faint lit shadow ray (a light far from the floor there): its share is below the comparison's absolute
    # tolerance, but without the 1/d^2 it is not, and the ratio tells
    (x, y), faint = next(
        (p, n) for p in places["lit"] for n in ex.reference_tree(*p)["nodes"]
        if n["kind"] == "shadow" and not n["occluded"] and 0 < max(n["radiance"]) < 2e-3
        and max(n["radiance"]) * d2(n, ex.reference_tree(*p)) > 0.01
    )  # fmt: skip
    tree = logged(ex.reference_tree(x, y))
    s = node_where(tree, lambda n: n["id"] == faint["id"])
    parent = next(n for n in tree["nodes"] if n["id"] == s["parent"])
    light = SCENE["lights"][s["light"]]
    far = sum((a - b) ** 2 for a, b in zip(light["position"], parent["hit"]["point"], strict=True))
    s["radiance"] = [c * far for c in s["radiance"]]  # I cos(theta) f without the 1 / d^2
    d = first(ex, tree)
    assert d["what"] == "attenuation" and "f_att" in d["message"], d
    x, y = places["lit"][0]  # a bright one, 1.6 times too bright: not the attenuation
    tree = logged(ex.reference_tree(x, y))
    s = node_where(tree, lambda n: n["kind"] == "shadow" and not n["occluded"] and max(n["radiance"]) > 1e-2)
    s["radiance"] = [c * 1.6 for c in s["radiance"]]
    d = first(ex, tree)
    assert d["what"] == "shading" and "shininess" in d["message"], d
    tree = logged(ex.reference_tree(x, y))
    hit = node_where(tree, lambda n: n.get("terms") and max(n["terms"]["diffuse"]) > 1e-3)
    hit["terms"]["specular"] = [c + 0.2 for c in hit["terms"]["specular"]]
    d = first(ex, tree)
    assert d["what"] == "shading" and "specular" in d["message"] and d["student"] == hit["id"], d


def test_explain_a_flipped_normal_inside_the_glass(ex, places):
    x, y = places["inside"][0]
    tree = logged(ex.reference_tree(x, y))
    ref = ex.reference_tree(x, y)
    inside = node_where(ref, lambda n: n["hit"] and not n["hit"]["front_face"])
    node = node_where(tree, lambda n: n["id"] == inside["id"])
    node["hit"]["normal"] = [-c for c in node["hit"]["normal"]]
    d = first(ex, tree)
    assert d["what"] == "normal" and "inside" in d["message"] and d["student"] == node["id"], d


def test_explain_the_reflection_sign_and_the_inverted_ior(ex, places):
    x, y = places["reflection"][0]
    tree = logged(ex.reference_tree(x, y))
    r = node_where(tree, lambda n: n["kind"] == "reflection")
    parent = next(n for n in tree["nodes"] if n["id"] == r["parent"])
    dvec, nvec = np.asarray(parent["direction"]), np.asarray(parent["hit"]["normal"])
    dvec = dvec / np.linalg.norm(dvec)
    r["direction"] = list(dvec + 2 * np.dot(dvec, nvec) * nvec)
    d = first(ex, tree)
    assert d["what"] == "reflection_direction" and "sign" in d["message"], d
    for x, y in places["entering"]:  # a pixel where the inverted ior still refracts (no false TIR)
        tree = logged(ex.reference_tree(x, y))
        t = node_where(tree, lambda n: n["kind"] == "transmission")
        parent = next(n for n in tree["nodes"] if n["id"] == t["parent"])
        dvec = np.asarray(parent["direction"]) / np.linalg.norm(parent["direction"])
        nvec = np.asarray(parent["hit"]["normal"])
        cos_i = -float(np.dot(dvec, nvec))
        eta = 1.5  # n2 / n1 where n1 / n2 = 1 / 1.5 belongs
        k = 1 - eta * eta * (1 - cos_i * cos_i)
        if k >= 0:
            break
    else:
        pytest.fail("no pixel where the inverted ior refracts")
    t["direction"] = list(eta * dvec + (eta * cos_i - math.sqrt(k)) * nvec)
    d = first(ex, tree)
    assert d["what"] == "refraction_direction" and "inverse" in d["message"], d


def test_explain_total_internal_reflection_both_ways_and_fresnel(ex, places):
    x, y = places["tir"][0]
    tree = logged(ex.reference_tree(x, y))
    ref = ex.reference_tree(x, y)
    at = node_where(ref, lambda n: n["end"] == "tir")
    mine = node_where(tree, lambda n: n["id"] == at["id"])
    extra = dict(copy.deepcopy(mine), id=10_000, parent=mine["id"], kind="transmission", t=None, hit=None)
    tree["nodes"].append(extra)
    d = first(ex, tree)
    assert d["what"] == "total_internal_reflection" and "critical angle" in d["message"], d
    x, y = places["entering"][0]
    tree = logged(ex.reference_tree(x, y))
    t = node_where(tree, lambda n: n["kind"] == "transmission")
    drop(tree, t["id"])
    d = first(ex, tree)
    assert d["what"] == "total_internal_reflection" and "no total internal reflection" in d["message"], d
    tree = logged(ex.reference_tree(x, y))
    r = node_where(tree, lambda n: n["kind"] == "reflection" and n["parent"] == t["parent"])
    r["weight"] = [c * 0.5 for c in r["weight"]]
    d = first(ex, tree)
    assert d["what"] == "fresnel" and "Fresnel" in d["message"] and d["student"] == r["id"], d


def test_explain_the_depth_limit_and_rays_too_many_or_too_few(ex, places):
    x, y = places["max_depth"][0]
    tree = logged(ex.reference_tree(x, y))
    ref = ex.reference_tree(x, y)
    at = node_where(ref, lambda n: n["end"] == "max_depth")
    mine = node_where(tree, lambda n: n["id"] == at["id"])
    tree["nodes"].append(dict(copy.deepcopy(mine), id=10_000, parent=mine["id"], kind="reflection"))
    d = first(ex, tree)
    assert d["what"] == "depth" and "max_depth" in d["message"] and d["student"] == 10_000, d
    # one level short: the deepest rays never traced
    tree = logged(ex.reference_tree(x, y))
    deepest = [n for n in ref["nodes"] if n["depth"] == SCENE["render"]["max_depth"] and n["kind"] != "shadow"]
    for n in deepest:
        if any(m["id"] == n["id"] for m in tree["nodes"]):
            drop(tree, n["id"])
    d = first(ex, tree)
    assert d["what"] == "depth" and "stops" in d["message"], d
    x, y = places["absorbed"][0]
    tree = logged(ex.reference_tree(x, y))
    ref = ex.reference_tree(x, y)
    at = node_where(ref, lambda n: n["end"] == "absorbed" and n["kind"] != "shadow")
    mine = node_where(tree, lambda n: n["id"] == at["id"])
    if at["depth"] + 1 <= SCENE["render"]["max_depth"]:
        tree["nodes"].append(dict(copy.deepcopy(mine), id=10_000, parent=mine["id"], kind="reflection"))
        d = first(ex, tree)
        assert d["what"] == "extra_ray" and "kr = kt = 0" in d["message"], d
    x, y = places["entering"][0]
    tree = logged(ex.reference_tree(x, y))
    t = node_where(tree, lambda n: n["kind"] == "transmission")
    r = node_where(tree, lambda n: n["kind"] == "reflection" and n["parent"] == t["parent"])
    drop(tree, r["id"])
    d = first(ex, tree)
    assert d["what"] == "missing_ray" and d["reference"] == r["id"], d


def test_explain_a_right_tree_but_a_linear_pixel_is_the_encoding(ex):
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.film import to_srgb8
    from tracer.rendering.progressive import render

    image = render(compile_scene(ex.scene)).image
    x, y = 20, 40
    shown = to_srgb8(image).astype(np.float64) / 255
    (answer,) = ex.compare({"trees": [logged(ex.reference_tree(x, y))]}, shown)
    assert answer["matches"], answer["differences"]
    linear = np.clip(image, 0, 1)  # no sRGB curve
    d = first(ex, logged(ex.reference_tree(x, y)), np.round(linear * 255).astype(np.uint8))
    assert d["what"] == "encoding" and "sRGB" in d["message"], d


def test_explain_every_what_is_in_the_contract():
    assert set(WHATS) == {
        "eye_ray", "hit", "normal", "shadow_acne", "shadow", "reflection_direction", "refraction_direction",
        "total_internal_reflection", "fresnel", "shading", "attenuation", "depth", "missing_ray", "extra_ray",
        "encoding",
    }  # fmt: skip


def test_treelog_every_error_at_its_path():
    good = {"id": 0, "parent": None, "kind": "eye", "origin": [0, 0, 0], "direction": [0, 0, -1], "t": None}
    log = {"trees": [
        {"pixel": [1, 2], "nodes": [dict(good, kind="eyes"), dict(good, id=1, parent=0, kind="shadow", t=-1)]},
        {"pixel": [64, 0], "nodes": [good, dict(good, id=0, parent=0, kind="reflection")]},
        {"pixel": [3, 3], "nodes": [good, dict(good, id=1, parent=2, kind="reflection"),
                                     dict(good, id=2, parent=1, kind="transmission", direction=[0, 0, 0])]},
        {"pixel": [3, 3], "nodes": [good, dict(good, id=1, parent=0, kind="shadow"),
                                     dict(good, id=2, parent=1, kind="reflection")]},
        7,
    ]}  # fmt: skip
    errors = {e["path"]: e["message"] for e in treelog.validate(log, 64, 48)}
    assert "eye" in errors["trees[0].nodes[0].kind"]
    assert ">= 0" in errors["trees[0].nodes[1].t"]
    assert "x in 0..63" in errors["trees[1].pixel"]
    assert "used twice" in errors["trees[1].nodes[1].id"]
    assert "cycle" in errors["trees[2].nodes[1].parent"] or "cycle" in errors["trees[2].nodes[2].parent"]
    assert "zero-length" in errors["trees[2].nodes[2].direction"]
    assert "logged twice" in errors["trees[3].pixel"]
    assert "shadow ray" in errors["trees[3].nodes[2].parent"]
    assert "JSON object" in errors["trees[4]"]
    assert treelog.validate(b"[1, 2") and "JSON" in treelog.validate(b"[1, 2")[0]["message"]
    assert treelog.validate({"trees": [{"pixel": [0, 0], "nodes": [good]}] * 65})[0]["path"] == "trees"
    assert "4 MB" in treelog.validate(b" " * (treelog.MAX_BYTES + 1))[0]["message"]
    assert treelog.validate({"trees": [{"pixel": [0, 0], "nodes": [dict(good, extra="kept out")]}]}) == []


def test_probes_one_per_region_ranked_by_summed_error():
    error = np.zeros((48, 64), np.float32)
    error[5:15, 5:15] = 0.6  # a large region
    error[8, 9] = 0.9  # its peak
    error[30:33, 40:43] = 0.8  # a small bright one
    error[31, 41] = 0.85  # its peak
    error[40, 2] = 0.05  # faint noise: never a probe
    found = probes.find(error, [{"x": 1, "y": 1, "why": "the corner"}], n=2)
    assert [(p.x, p.y) for p in found] == [(1, 1), (9, 8), (41, 31)]
    assert found[0].why == "the corner"
    assert "largest region (100 pixels)" in found[1].why
    assert "0.90" in found[1].why
    assert "region 2 of 2" in found[2].why
    assert found[2].region == 9
    assert probes.find(np.full((8, 8), 0.05, np.float32)) == []
    spread = probes.find(np.pad(np.full((40, 40), 0.5, np.float32), 4), n=4)  # one big region: 4 places, apart
    assert len(spread) == 4
    assert all(max(abs(a.x - b.x), abs(a.y - b.y)) >= 6 for i, a in enumerate(spread) for b in spread[i + 1 :])


def test_explain_the_command_line_prints_probes_and_the_diagnosis(ex, tmp_path, capsys):
    """python -m tracer explain SCENE --image PNG [--trees LOG]: probes; a right log (exit 0), a log with the eye
    ray through the pixel's corner (exit 2, `eye_ray` with what to fix), a broken log (exit 1, its line and
    column), --json."""
    from PIL import Image

    from tracer.__main__ import main
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.film import to_srgb8
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    jittered = dict(SCENE, sampler={"type": "jittered", "spp": 4})
    scene_path = tmp_path / "scene.json"
    scene_path.write_text(json.dumps(jittered))
    image = render(compile_scene(load_scene(jittered)[0])).image  # the reference as the command renders it
    wrong = image.copy()
    wrong[30:40, 10:20] = 0  # a black square over the floor
    Image.fromarray(to_srgb8(wrong)).save(tmp_path / "mine.png")
    right_log = {"trees": [logged(ex.reference_tree(40, 35)), logged(ex.reference_tree(50, 10))]}
    (tmp_path / "right.json").write_text(json.dumps(right_log))
    args = [str(scene_path), "--image", str(tmp_path / "mine.png")]
    assert main(["explain", *args]) == 0
    out = capsys.readouterr().out
    assert "probes (" in out and "largest region" in out, out
    probes_said = [tuple(int(c) for c in line.split(":")[0].strip(" ()").split(", ")) for line in out.splitlines()
                   if line.startswith("  (")]  # fmt: skip
    assert probes_said and all(8 <= x < 22 and 28 <= y < 42 for x, y in probes_said), probes_said
    assert main(["explain", *args, "--trees", str(tmp_path / "right.json")]) == 0
    assert "pixel (40, 35): your tree matches" in capsys.readouterr().out
    bad = copy.deepcopy(right_log)
    forward, right, up, h, aspect = ex.camera_frame()
    bad["trees"][1]["nodes"][0]["direction"] = list(forward + (2 * 50 / ex.width - 1) * h * aspect * right
                                                    + (1 - 2 * 10 / ex.height) * h * up)  # fmt: skip
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    assert main(["explain", *args, "--trees", str(tmp_path / "bad.json"), "--json"]) == 2
    result = json.loads(capsys.readouterr().out)
    assert result["trees"][0]["matches"]
    assert not result["trees"][1]["matches"]
    assert result["trees"][1]["differences"][0]["what"] == "eye_ray"
    (tmp_path / "broken.json").write_text('{"trees": [\n  {"pixel": [1, 2], "nodes": [{"id": 0}]}]}')
    assert main(["explain", *args, "--trees", str(tmp_path / "broken.json")]) == 1
    err = capsys.readouterr().err
    assert "broken.json:2:" in err and "trees[0].nodes[0].parent" in err, err
