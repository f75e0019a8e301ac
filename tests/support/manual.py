"""Staff-graded items of the course tests (tests/server/course/test_api_manual.py, tests/web/test_web_grading_queue.py,
tests/web/test_web_course_story.py): the statistics tests' small assignment (6 auto points) with two manual items,
creativity (3 points: three levels) and lighting (2 points: two levels); `publish_class` publishes it and grades
ann's and bea's submissions."""

from __future__ import annotations

import copy

from tests.support.api import bearer, wait_for
from tests.support.stats import red, reference, small_spec

MANUAL = [
    {"name": "creativity", "points": 3, "instructions": "More than the starter scene?",
     "rubric": [{"name": "new objects", "points": 2, "description": "two or more"},
                {"name": "a story", "points": 0.5}, {"name": "copied", "points": -3}]},
    {"name": "lighting", "points": 2, "rubric": [{"name": "area light", "points": 2}, {"name": "mood", "points": 1}]},
]  # fmt: skip


def manual_spec(manual: list[dict] = MANUAL) -> dict:
    """The small assignment with `manual` items (a copy: a test may change it)."""
    return {**small_spec(), "manual": copy.deepcopy(manual)}


def publish_class(c, url: str, headers: dict, deadline: str, roster: str) -> tuple[str, dict, dict]:
    """The small assignment with MANUAL published at `url` (POST, `headers` the instructor's) on client `c` (a
    TestClient or an httpx.Client), its `roster` CSV uploaded, ann's reference scene and bea's red one without
    glass (6 and 2 auto points) submitted and graded: (its id, each student's bearer headers, ann's and bea's
    submission ids)."""
    r = c.post(url, json={"spec": manual_spec(), "deadline": deadline}, headers=headers)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    r = c.post(f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv", **headers})
    assert r.status_code == 200, r.text
    tokens = {s["id"]: bearer(s["token"]) for s in r.json()["students"]}
    sids = {}
    for who, scene in (("ann", reference()), ("bea", red(glass=False))):
        r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=tokens[who])
        assert r.status_code == 202, r.text
        sids[who] = r.json()["id"]
    for sid in sids.values():
        u = f"/api/assignments/{aid}/submissions/{sid}"
        wait_for(lambda u=u: c.get(u, headers=headers).json()["status"] == "graded", 240, f"{sid} graded", 0.1)
    return aid, tokens, sids
