"""A small assignment of the course tests (its spec, reference and a good and a bad hand-in), from
tests/server/course/test_dashboard.py, used by the course's API and page tests."""

from __future__ import annotations

import copy
import json

from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"


SIZE = (32, 24)  # every render of the small assignment: its reference mean renders in a second or two


def small_reference() -> dict:
    ref = json.loads((EXAMPLE / "reference.json").read_text())
    ref["film"] = {"width": SIZE[0], "height": SIZE[1]}
    ref["sampler"] = {"type": "jittered", "spp": 4}
    return ref


def small_spec(inline: bool = True) -> dict:
    """The example's assignment, smaller: two requirements and two image tests (max 6 for a scene, 4 for an
    image: validity and the image tests); its reference inline, or named as the file 'reference.json' (the
    page sends the file beside the spec)."""
    return {
        "version": 1,
        "name": "HW 0: a small glass ball",
        "description": "The example's scene at 32 x 24 pixels.",
        "render": {"width": SIZE[0], "height": SIZE[1], "seed": 7},
        "limits": {"max_seconds": 30, "max_spp": 16},
        "validity": {"points": 1},
        "requirements": [
            {"name": "a glass object", "points": 1, "check": "transmissive_material"},
            {"name": "an area light", "points": 1, "check": "area_light"},
        ],
        "reference": {
            "scene": small_reference() if inline else "reference.json",
            "spp": 16,
            "psnr": {"points": 1},
            "pixels": {"points": 2},
        },
        "image": {"spp": 4},
    }


def good_scene() -> dict:
    """The reference scene itself at 4 spp: full marks."""
    return small_reference()


def bad_scene() -> dict:
    scene = copy.deepcopy(small_reference())
    scene["objects"][1]["radius"] = -1  # invalid: a negative radius
    return scene
