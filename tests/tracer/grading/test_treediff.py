"""Two ray trees compared (tracer/grading/treediff.py) on hand-made trees: which node first differs, why (`what`),
the paths on each side, and the sentence a student reads. The trees are in the format of SCENE_FORMAT.md."""

from __future__ import annotations

import copy

import pytest

from tracer.grading.treediff import first_difference, node_at, path_of


def node(
    id,
    parent,
    kind,
    *,
    depth=1,
    t=4.0,
    obj=3,
    name="red ball",
    material="red",
    weight=1.0,
    terms=None,
    light=None,
    occluded=None,
    radiance=0.2,
    direction=(0.0, 0.0, -1.0),
    end=None,
):
    hit = None
    if t is not None:
        hit = {
            "point": [0.0, 0.0, -t],
            "normal": [0.0, 0.0, 1.0],
            "object": obj,
            "object_name": name,
            "material": material,
            "front_face": True,
        }
    if kind == "shadow" and not occluded:
        hit, t = None, None
    return {
        "id": id,
        "parent": parent,
        "kind": kind,
        "depth": depth,
        "origin": [0.0, 0.0, 0.0],
        "direction": list(direction),
        "t": t,
        "hit": hit,
        "weight": [weight] * 3,
        "radiance": [radiance] * 3,
        "terms": terms if kind != "shadow" and hit else None,
        "light": light,
        "occluded": occluded,
        "end": end,
    }


TERMS = {"ambient": [0.06, 0.012, 0.01], "diffuse": [0.5, 0.1, 0.08], "specular": [0.02, 0.02, 0.02]}


def tree() -> dict:
    """An eye ray on a red ball with two shadow rays (lights 0 and 1) and a reflection ray onto the floor, which
    has a shadow ray of its own."""
    return {
        "pixel": [5, 6],
        "sample": 0,
        "color": [0.3, 0.1, 0.1],
        "nodes": [
            node(0, None, "eye", terms=copy.deepcopy(TERMS)),
            node(1, 0, "shadow", light=0, occluded=False, radiance=0.9, direction=(0.0, 1.0, 0.0), end="light"),
            node(2, 0, "shadow", light=1, occluded=False, radiance=0.4, direction=(1.0, 0.0, 0.0), end="light"),
            node(
                3,
                0,
                "reflection",
                depth=2,
                weight=0.3,
                obj=0,
                name="floor",
                material="floor",
                t=2.0,
                terms={"ambient": [0.05] * 3, "diffuse": [0.3] * 3, "specular": [0.0] * 3},
                end="absorbed",
            ),
            node(4, 3, "shadow", depth=2, weight=0.3, light=0, occluded=False, radiance=0.7, direction=(0, 1, 0)),
        ],
    }


def test_treediff_identical_trees_agree():
    assert first_difference(tree(), tree()) is None


def test_treediff_paths_are_child_indices_in_id_order():
    t = tree()
    assert [path_of(t, i) for i in range(5)] == [[], [0], [1], [2], [2, 0]]
    assert node_at(t, [2, 0])["id"] == 4 and node_at(t, [])["id"] == 0
    with pytest.raises(IndexError):
        node_at(t, [3])


def test_treediff_another_colour_is_the_material_of_the_eye_rays_hit():
    student = tree()
    student["nodes"][0]["terms"]["diffuse"] = [0.1, 0.1, 0.5]  # a blue ball
    d = first_difference(student, tree())
    assert d["what"] == "material"
    assert d["student"] == []
    assert d["reference"] == []
    assert d["nodes"] == {"student": 0, "reference": 0}
    assert d["message"] == (
        "Where your eye ray hits red ball (material 'red'), as the reference's does, the light it reflects there "
        "differs (yours against the reference's): diffuse (0.1, 0.1, 0.5) against (0.5, 0.1, 0.08). The material "
        "differs (kd: its colour), or a light's intensity."
    )


def test_treediff_another_object_hit_comes_before_its_material():
    student = tree()
    student["nodes"][0].update(t=6.0)
    student["nodes"][0]["hit"].update(point=[0.0, 0.0, -6.0], object=0, object_name="floor")
    student["nodes"][0]["terms"]["diffuse"] = [0.3] * 3
    d = first_difference(student, tree())
    assert d["what"] == "object"
    assert d["student"] == d["reference"] == []
    assert d["message"] == (
        "Your eye ray hits 'floor' (object 0) at t = 6; the reference's hits 'red ball' (object 3) "
        "at t = 4: another object is there (check the objects' places and sizes)."
    )
    missed = tree()
    missed["nodes"][3].update(hit=None, t=None, terms=None, end="miss")
    d = first_difference(tree(), missed)
    assert d["what"] == "object"
    assert d["student"] == d["reference"] == [2]
    assert "the reference's leaves the scene" in d["message"]


def test_treediff_the_same_surface_under_another_index_or_name_agrees():
    """Objects are compared by where the ray hits them (t and the normal), not by their index in the list."""
    student = tree()
    student["nodes"][0]["hit"].update(object=7, object_name="ball")
    assert first_difference(student, tree()) is None


def test_treediff_another_weight_is_the_reflection_rays():
    student = tree()
    student["nodes"][3]["weight"] = [0.6] * 3
    student["nodes"][4]["weight"] = [0.6] * 3
    d = first_difference(student, tree())
    assert d["what"] == "weight"
    assert d["student"] == d["reference"] == [2]
    assert d["message"] == (
        "Your reflection ray (depth 2) carries weight 0.6; the reference's 0.3: the material at "
        "red ball (material 'red') reflects or transmits another share (its kr, or fresnel)."
    )


def test_treediff_a_ray_only_one_has_is_missing_marked_on_the_others_parent():
    reference = tree()
    student = tree()
    del student["nodes"][3:]  # no reflection ray (kr = 0)
    student["nodes"][0]["radiance"] = [0.1] * 3
    d = first_difference(student, reference)
    assert d["what"] == "missing"
    assert d["reference"] == [2]
    assert d["student"] == []
    assert d["nodes"] == {"student": 0, "reference": 3}
    assert "casts a reflection ray (depth 2); yours, at red ball (material 'red'), does not (check kr" in d["message"]
    d = first_difference(reference, student)  # the other way round: the student's extra ray
    assert d["what"] == "missing"
    assert d["student"] == [2]
    assert d["reference"] == []
    assert d["message"].startswith("Your red ball (material 'red') casts a reflection ray (depth 2); the reference's")


def test_treediff_shadow_rays_pair_by_their_light():
    """A student without light 0: their only shadow ray goes to light 1 and pairs with the reference's second."""
    student = tree()
    del student["nodes"][1]
    d = first_difference(student, tree())
    assert d["what"] == "missing"
    assert d["reference"] == [0]
    assert d["student"] == []
    assert "shadow ray towards light 0" in d["message"]


def test_treediff_a_blocked_shadow_ray_comes_before_the_terms_it_changes():
    student = tree()
    student["nodes"][1].update(
        occluded=True,
        end="absorbed",
        radiance=[0.0] * 3,
        t=1.0,
        hit={"point": [0, 1, 0], "normal": [0, -1, 0], "object": 5, "object_name": "roof"},
    )
    student["nodes"][0]["terms"]["diffuse"] = [0.2, 0.04, 0.03]
    d = first_difference(student, tree())
    assert d["what"] == "shadow"
    assert d["student"] == d["reference"] == [0]
    assert d["message"] == (
        "Your shadow ray towards light 0 from red ball (material 'red') is blocked by 'roof'; the "
        "reference's reaches it: an object casts another shadow here."
    )


def test_treediff_a_light_elsewhere_or_brighter():
    moved = tree()
    moved["nodes"][2]["direction"] = [0.0, 0.7, 0.7]
    d = first_difference(moved, tree())
    assert d["what"] == "light"
    assert d["student"] == [1]
    assert "the light is elsewhere" in d["message"]
    brighter = tree()
    brighter["nodes"][2]["radiance"] = [0.8] * 3
    d = first_difference(brighter, tree())
    assert d["what"] == "light"
    assert d["student"] == [1]
    assert "intensity" in d["message"]


def test_treediff_the_first_difference_is_depth_first():
    """Two differences: the reflection ray's shadow ray (deeper, but under the first child compared) and
    nothing else; and the camera before anything."""
    student = tree()
    student["nodes"][4]["occluded"] = True
    student["nodes"][4]["hit"] = {"point": [0, 0, 0], "normal": [0, 1, 0], "object": 2, "object_name": None}
    d = first_difference(student, tree())
    assert d["what"] == "shadow"
    assert d["student"] == [2, 0]
    assert "is blocked by object 2" in d["message"]
    student["nodes"][0]["direction"] = [0.1, 0.0, -0.995]
    assert first_difference(student, tree())["what"] == "camera"


def test_treediff_a_miss_with_another_background():
    reference = tree()
    reference["nodes"][3].update(hit=None, t=None, terms=None, end="miss", radiance=[0.3, 0.45, 0.7])
    del reference["nodes"][4]
    student = copy.deepcopy(reference)
    student["nodes"][3]["radiance"] = [0.0] * 3
    d = first_difference(student, reference)
    assert d["what"] == "background"
    assert d["student"] == [2]
    assert "the background (or the fog) differs" in d["message"]


def test_treediff_tolerates_float_noise_only():
    student = tree()
    student["nodes"][0]["terms"]["diffuse"] = [0.5 * (1 + 2e-4), 0.1, 0.08]
    assert first_difference(student, tree()) is None
    student["nodes"][0]["terms"]["diffuse"] = [0.5 * (1 + 5e-3), 0.1, 0.08]
    assert first_difference(student, tree())["what"] == "material"
