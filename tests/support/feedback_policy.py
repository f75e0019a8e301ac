"""The feedback-policy tests' assignment (tests/server/course/test_feedback_policy.py,
tests/web/test_web_feedback_policy.py):
the docs' example policy, the example assignment at 32 x 24, a student's scene with its lights dimmed."""

from __future__ import annotations

import json

from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
POLICY = {"feedback": {"tests": {"pixels": "after_deadline"}, "score": "now"}}  # docs/assignments.md's example


def reference() -> dict:
    ref = json.loads((EXAMPLE / "reference.json").read_text())
    ref["film"] = {"width": 32, "height": 24}
    ref["sampler"] = {"type": "jittered", "spp": 4}
    return ref


def spec() -> dict:
    s = json.loads((EXAMPLE / "assignment.json").read_text())
    s["render"] = {"width": 32, "height": 24, "seed": 7}
    s["reference"]["scene"] = reference()
    s["reference"]["spp"] = 16
    s["image"] = {"spp": 4}
    return s


def dimmed() -> dict:
    """The reference with its lights at a fifth: every requirement met, every image test missed."""
    s = reference()
    for light in s["lights"]:
        for key in ("intensity", "radiance", "power"):
            if key in light:
                light[key] = [v / 5 for v in light[key]] if isinstance(light[key], list) else light[key] / 5
    return s
