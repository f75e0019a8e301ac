"""A grading run that is slow to finish: the example assignment with a slow student
(tests/server/course/test_api_assignments_restart.py and the Redis one)."""

from __future__ import annotations

import copy
import json

from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"


def spec() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def slow_alice() -> dict:
    scene = copy.deepcopy(json.loads((EXAMPLE / "class" / "alice.json").read_text()))
    scene["sampler"] = {"type": "jittered", "spp": 64}
    scene["render"]["light_samples"] = 16
    return scene
