"""Similarity reports (issue #41, item 6): a scene's canonical facts (tracer/grading/canonical.py) forget names,
order, defaults and small nudges, and keep what a student made; the report (tracer/grading/similarity.py) flags
a copied scene first and no honest student of a class that all started from one starter scene."""

from __future__ import annotations

import copy
import json
import random

import numpy as np
import pytest

from bench.similarity import disguised, honest, image_class, picture, png, scene_class, starter
from tracer.grading import canonical as canon
from tracer.grading import similarity
from tracer.grading.similarity import Work


def facts(scene: dict) -> set[str]:
    return canon.canonical(scene).facts


def test_canonical_forgets_the_order_of_objects_and_lights():
    s = honest(random.Random(3))
    t = copy.deepcopy(s)
    t["objects"].reverse()
    t["lights"].reverse()
    assert facts(t) == facts(s)


def test_canonical_forgets_material_names_and_reads_them_by_value():
    s = starter()
    t = copy.deepcopy(s)
    t["materials"] = {"ground_2": s["materials"]["floor"], "shiny": s["materials"]["red"]}
    t["objects"][0]["material"], t["objects"][1]["material"] = "ground_2", "shiny"
    inline = copy.deepcopy(s)
    inline["objects"][1]["material"] = s["materials"]["red"]  # the same material written into the object
    assert facts(t) == facts(s) == facts(inline)
    where = ",".join(canon.grid(x, False, canon.ANCHOR_SCALE) for x in (0, 0.5, 0))
    assert f"sphere@({where}).material.ks={canon.grid(0.3)}" in facts(s)


def test_canonical_forgets_names_defaults_and_equal_triples():
    s = starter()
    t = copy.deepcopy(s)
    t["name"] = "Mine"
    t["objects"][1]["name"] = "my ball"
    t["materials"]["red"]["kr"] = 0  # a default written out
    t["materials"]["red"]["ks"] = [0.3, 0.3, 0.3]  # a triple of one number is that number
    t["camera"]["vup"] = [0, 1, 0]  # the default again
    assert facts(t) == facts(s)


def test_canonical_a_changed_value_or_a_moved_object_is_a_different_fact():
    s = starter()
    t = copy.deepcopy(s)
    t["materials"]["red"]["ks"] = 0.6
    where = ",".join(canon.grid(x, False, canon.ANCHOR_SCALE) for x in (0, 0.5, 0))
    assert f"sphere@({where}).material.ks={canon.grid(0.3)}" in facts(s) - facts(t)
    u = copy.deepcopy(s)
    u["objects"][1]["center"] = [1.5, 0.5, 0]
    assert {f for f in facts(u) - facts(s) if f.startswith(f"sphere@({canon.grid(1.5, False, canon.ANCHOR_SCALE)},")}


@pytest.mark.parametrize("scale", [1, canon.ANCHOR_SCALE])
@pytest.mark.parametrize("delta", [0.001, -0.001, 0.002])
def test_canonical_grid_a_nudge_keeps_a_number_on_one_of_the_two_grids(delta, scale):
    """Half a step apart, the two grids never both have a line between x and x + delta (small deltas), and
    no line lies on a number written with two decimals."""
    for x in np.linspace(-7.3, 250.0, 20011):
        x = float(x)
        one, two = canon.grid(x, False, scale), canon.grid(x, True, scale)
        assert one == canon.grid(x + delta, False, scale) or two == canon.grid(x + delta, True, scale), x
    for x in np.arange(-99, 99) / 100:  # -0.99 .. 0.98: 0.001 either way stays in its cell on both grids
        assert canon.grid(x, False, scale) == canon.grid(x + delta, False, scale), x
        assert canon.grid(x, True, scale) == canon.grid(x + delta, True, scale), x


def test_canonical_a_nudged_copy_keeps_most_facts():
    rng = random.Random(5)
    s = honest(rng)
    d = disguised(rng, s)
    assert similarity.jaccard_distance(facts(s), facts(d)) < 0.2
    given = canon.canonical(starter())
    own_s, own_d = canon.canonical(s).own(given), canon.canonical(d).own(given)
    assert similarity.jaccard_distance(own_s.facts, own_d.facts) < 0.3


def test_canonical_the_starter_discounted_leaves_nothing_of_the_starter():
    given = canon.canonical(starter())
    assert canon.canonical(starter()).own(given).facts == set()
    s = honest(random.Random(9))
    own = canon.canonical(s).own(given)
    assert own.facts
    assert not own.facts & given.facts
    assert all(fact.split("=")[0] == shown[0] for fact, shown in own.shown.items())
    assert any(shown[1].startswith("sphere@(") and shown[1] != shown[0] for shown in own.shown.values())


def test_canonical_what_is_no_scene():
    assert canon.read(b"not json") is None and canon.read(b"[1, 2]") is None
    assert canon.canonical({"objects": [{"type": "sphere"}, 3], "lights": "x"}) is not None  # read as far as it goes


def test_similarity_minhash_candidates_find_a_close_pair_and_estimate_jaccard():
    a = {f"f{i}" for i in range(100)}
    b = {f"f{i}" for i in range(10, 110)}  # Jaccard 90/110
    far = {f"g{i}" for i in range(100)}
    sigs = np.array([similarity.signature(x) for x in (a, b, far)])
    assert (0, 1) in similarity.candidates([s.view(np.uint8) for s in sigs], similarity.BANDS)
    est = similarity.estimated_distances(sigs)
    assert abs(est[0, 1] - (1 - 90 / 110)) < 0.15  # 126 permutations: a standard error of about 0.035
    assert est[0, 2] > 0.9


def test_similarity_usual_threshold_is_below_the_class_and_at_most_half():
    u = similarity.usual([1.0] * 20)
    assert u["typical"] == 1.0
    assert u["threshold"] == 0.5
    spread_out = similarity.usual([0.2, 0.4, 0.5, 0.6, 0.8, 0.9, 1.0])
    assert spread_out["threshold"] < 0.6 * 0.5
    assert similarity.usual([0.1, 0.9])["threshold"] is None  # too few to know what is usual


def scene_works(n: int, copies: int, seed: int = 1) -> tuple[list[Work], set[frozenset]]:
    scenes, copied = scene_class(n, copies, seed)
    return [Work(who, "scene", json.dumps(s).encode()) for who, s in scenes], copied


def test_similarity_report_flags_the_copied_scene_first_and_no_honest_pair():
    works, copied = scene_works(24, 1)
    out = similarity.report(works, starter())
    assert out["pairs"], out["closest"]
    first = out["pairs"][0]
    assert frozenset((first["a"], first["b"])) in copied
    assert all(frozenset((p["a"], p["b"])) in copied for p in out["pairs"])
    # most of the copy's facts match (one of its numbers, 1.82, sits 0.0004 below a line of the first grid: the
    # nudge moves its object's first-grid facts, and the second grid's still match)
    assert first["score"] < 0.3
    assert first["typical"] == out["groups"]["scene"]["typical"]
    shared = [f for f in first["facts"] if f["shared"]]
    assert shared
    assert all(f["a"] is not None and f["b"] is not None for f in shared)
    assert not any(f["path"].startswith("plane@") for f in first["facts"])  # the starter's floor: discounted


def test_similarity_report_without_a_starter_the_class_common_facts_are_discounted():
    works, copied = scene_works(24, 1)
    out = similarity.report(works, None)  # the starter's facts are shared by all: discounted as common
    assert {frozenset((p["a"], p["b"])) for p in out["pairs"]} == copied
    assert out["groups"]["scene"]["common_facts"] > 0


def test_similarity_report_skips_the_starter_handed_in_and_what_is_no_scene():
    works, _ = scene_works(8, 0)
    unchanged = json.dumps(starter()).encode()
    works += [Work("lazy1", "scene", unchanged), Work("lazy2", "scene", unchanged), Work("broken", "scene", b"{not")]
    out = similarity.report(works, starter())
    assert {s["student"] for s in out["skipped"]} == {"lazy1", "lazy2", "broken"}
    assert out["pairs"] == []  # two unchanged starters are no evidence of anything


def test_similarity_report_a_small_class_flags_nothing():
    works, _ = scene_works(4, 1)
    out = similarity.report(works, starter())
    assert out["pairs"] == []
    assert out["groups"]["scene"]["threshold"] is None


def test_similarity_report_images_a_copied_picture_with_noise_is_flagged():
    works_raw, copied = image_class(16, 1, seed=4)
    works = [Work(who, "png", data) for who, data in works_raw]
    works.append(Work("bad", "png", b"not a png"))
    out = similarity.report(works)
    assert {frozenset((p["a"], p["b"])) for p in out["pairs"]} == copied
    assert out["pairs"][0]["kind"] == "image"
    assert out["skipped"][0]["student"] == "bad"
    assert png(picture(np.random.default_rng(0)))[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    "scene",
    [
        {"objects": 5, "lights": {"a": 1}, "materials": [1]},
        {"objects": [{"type": ["sphere"], "center": [0, 0, 0]}], "lights": [{"type": {"x": 1}}]},
        {"objects": [{"type": "sphere", "material": ["x"], "center": "here", "radius": None}]},
        {"objects": [{"type": "mesh", "vertices": [[0, 0, 0], "x", [1, 2]], "faces": [[0, 1, 2]] * 40}]},
        {"camera": [1, 2], "film": "big", "fog": {"density": float("nan")}, "background": [1e308, -1e308, 0]},
    ],
)
def test_canonical_a_scene_written_wrong_is_read_as_far_as_it_goes(scene):
    """What a student handed in may be no valid scene (an invalid submission is still compared): its facts
    are read where they can be, and nothing raises."""
    c = canon.canonical(scene)
    assert c is not None
    works = [Work(f"s{i}", "scene", json.dumps(x).encode()) for i, x in enumerate([scene] * 3)]
    similarity.report(works)


def test_similarity_report_what_the_task_asks_of_everyone_is_no_evidence():
    """Every student also makes what the task asks for, the same way (a glass ball at the same place, with the
    textbook's glass): those facts are the class's common ones, discounted like the starter's, and no honest pair
    comes close because of them."""
    scenes, copied = scene_class(20, 1, seed=7)
    works = []
    for who, s in scenes:
        s["objects"].append(
            {"type": "sphere", "center": [0, 1, -1], "radius": 0.5, "material": {"kd": 0, "kt": 1, "ior": 1.5}}
        )
        works.append(Work(who, "scene", json.dumps(s).encode()))
    out = similarity.report(works, starter())
    assert {frozenset((p["a"], p["b"])) for p in out["pairs"]} == copied
    assert out["groups"]["scene"]["common_facts"] >= 8  # the glass ball's facts, on both grids
    assert not any(f["path"].startswith("sphere@(0,1,-1)") for f in out["pairs"][0]["facts"])
