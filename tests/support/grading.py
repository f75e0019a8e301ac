"""The example class of grading (scenes/grading/): its folder, its students' scenes and its assignment as a dict, for
tests/tracer/grading/test_grading.py and the service's grading tests."""

from __future__ import annotations

import json

from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"


ASSIGNMENT = EXAMPLE / "assignment.json"


CLASS = EXAMPLE / "class"


def assignment_dict() -> dict:
    return json.loads(ASSIGNMENT.read_text())
