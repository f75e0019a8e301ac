"""The class-statistics tests' assignment and scenes (tests/server/course/test_api_stats.py,
tests/web/test_web_class_stats.py):
the example's reference scene at 32 x 24, a spec of 6 points, a red-sky scene."""

from __future__ import annotations

import json

from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
SIZE = (32, 24)


def reference() -> dict:
    ref = json.loads((EXAMPLE / "reference.json").read_text())
    ref["film"] = {"width": SIZE[0], "height": SIZE[1]}
    ref["sampler"] = {"type": "jittered", "spp": 4}
    return ref


def small_spec() -> dict:
    """Validity 1, 'a glass object' 1, 'an area light' 1, psnr 1, pixels 2: 6 points for a scene."""
    return {
        "version": 1,
        "name": "HW 0: statistics",
        "render": {"width": SIZE[0], "height": SIZE[1], "seed": 7},
        "limits": {"max_seconds": 30, "max_spp": 16},
        "validity": {"points": 1},
        "requirements": [
            {"name": "a glass object", "points": 1, "check": "transmissive_material"},
            {"name": "an area light", "points": 1, "check": "area_light"},
        ],
        "reference": {"scene": reference(), "spp": 16, "psnr": {"points": 1}, "pixels": {"points": 2}},
        "image": {"spp": 4},
    }


def red(glass: bool) -> dict:
    """A red sky (both image tests fail); with or without the glass (its requirement): 3 or 2 points."""
    scene = reference()
    scene["background"] = [1.0, 0.0, 0.0]
    if not glass:
        scene["materials"]["glass"] = {"kd": 0.5}
    return scene
