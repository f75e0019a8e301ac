"""Staff-graded items of the course tests (tests/server/course/test_api_manual.py, tests/web/test_web_grading_queue.py,
tests/web/test_web_course_story.py): the statistics tests' small assignment (6 auto points) with two manual items,
creativity (3 points: three levels) and lighting (2 points: two levels)."""

from __future__ import annotations

import copy

from tests.support.stats import small_spec

MANUAL = [
    {"name": "creativity", "points": 3, "instructions": "More than the starter scene?",
     "rubric": [{"name": "new objects", "points": 2, "description": "two or more"},
                {"name": "a story", "points": 0.5}, {"name": "copied", "points": -3}]},
    {"name": "lighting", "points": 2, "rubric": [{"name": "area light", "points": 2}, {"name": "mood", "points": 1}]},
]  # fmt: skip


def manual_spec(manual: list[dict] = MANUAL) -> dict:
    """The small assignment with `manual` items (a copy: a test may change it)."""
    return {**small_spec(), "manual": copy.deepcopy(manual)}
