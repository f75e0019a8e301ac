"""Assignments (server/course/, server/api/routes/assignments.py, docs/assignments.md): publish the example
assignment of scenes/grading/, upload a roster, submit as students (scenes and images), read what each may
see, and export the grades. Time is the app's injectable clock (`app.state.clock`): the tests move it past
deadlines, never sleep to one. Students' grades are the example class's (tests/test_grading.py)."""

from __future__ import annotations

import base64
import csv
import io
import json
from datetime import UTC, datetime, timedelta

import pytest
from conftest import ROOT
from test_api_support import INSTRUCTOR, api_client, bearer, student_token, wait_for

EXAMPLE = ROOT / "scenes" / "grading"
CLASS = EXAMPLE / "class"
T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)  # the tests' "now" (the app's clock is set to it)
DEADLINE = T0 + timedelta(days=2)
TEACHER = bearer(INSTRUCTOR)


def spec(inline: bool = True) -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    if inline:
        a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def scene_text(name: str) -> str:
    return (CLASS / f"{name}.json").read_text()


def image(name: str) -> dict:
    path = next(CLASS.glob(f"{name}.*"))
    return {"image": base64.b64encode(path.read_bytes()).decode(), "format": path.suffix[1:]}


class Clock:
    """The app's clock, set by the test."""

    def __init__(self, now: datetime):
        self.now = now

    def __call__(self) -> datetime:
        return self.now


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    data = tmp_path_factory.mktemp("assignments-data")
    with api_client(data, workers=1, instructor_token=INSTRUCTOR, token=INSTRUCTOR, max_submissions_per_hour=6) as c:
        c.app.state.clock = Clock(T0)
        yield c


@pytest.fixture
def clock(app):
    app.app.state.clock = Clock(T0)
    yield app.app.state.clock
    app.app.state.clock.now = T0


def publish(client, **policy) -> dict:
    body = {"spec": spec(), "deadline": DEADLINE.isoformat(), **policy}
    r = client.post("/api/assignments", json=body)
    assert r.status_code == 201, r.text
    assert r.headers["location"] == f"/api/assignments/{r.json()['id']}"
    return r.json()


def roster(client, aid: str, rows: list[tuple[str, str, str]]) -> dict[str, dict]:
    text = "id,name,email\n" + "".join(f"{i},{n},{e}\n" for i, n, e in rows)
    r = client.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv"})
    assert r.status_code == 200, r.text
    return {s["id"]: s for s in r.json()["students"]}


def submit(client, aid: str, token: str, body: dict, status: int = 202) -> dict:
    r = client.post(f"/api/assignments/{aid}/submissions", json=body, headers=bearer(token))
    assert r.status_code == status, r.text
    return r.json()


def finished(client, aid: str, sid: str, token: str = INSTRUCTOR, timeout: float = 120) -> dict:
    url = f"/api/assignments/{aid}/submissions/{sid}"

    def done():
        s = client.get(url, headers=bearer(token)).json()
        return s["status"] in ("graded", "invalid", "failed") and s

    return wait_for(done, timeout, f"submission {sid} graded", interval=0.1)


def grades(client, aid: str) -> list[dict]:
    r = client.get(f"/api/assignments/{aid}/grades.csv", headers=TEACHER)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv"), r.text
    return list(csv.DictReader(io.StringIO(r.text)))


# ------------------------------------------------------------------------------------- the flow


def test_assignments_publish_roster_submit_and_grade_the_example(app, clock):
    """Three students submit alice's scene, carol's broken one and grace's PNG: graded once each as the
    example class is (13, invalid, 7), the invalid one costing no attempt; a test whose feedback is shown
    after the deadline is hidden until the clock passes it; grades.csv has one row per roster student."""
    a = publish(app, max_submissions=3, counts="best", feedback={"tests": {"pixels": "after_deadline"}, "score": "now"})
    aid = a["id"]
    students = roster(app, aid, [("s1", "Alice A", "a@x.edu"), ("s2", "Carol C", "c@x.edu"),
                                 ("s3", "Grace G", "g@x.edu"), ("s4", "Nobody N", "n@x.edu")])  # fmt: skip
    tok = {k: v["token"] for k, v in students.items()}
    assert all(v["link"].endswith(f"/assignments/{aid}#token={v['token']}") for v in students.values())

    b = app.get(f"/api/assignments/{aid}", headers=bearer(tok["s1"])).json()
    assert b["name"] == spec()["name"] and b["deadline"] == DEADLINE.isoformat().replace("+00:00", "Z")
    assert [(r["name"], r["points"]) for r in b["requirements"]][:2] == [("a glass object", 2), ("an area light", 1)]
    assert b["submissions_left"] == 3 and b["time_left"] == 2 * 86400 and "spec" not in b

    alice = submit(app, aid, tok["s1"], {"scene": json.loads(scene_text("alice"))})
    assert alice["status"] in ("queued", "grading") and alice["score"] is None
    carol = submit(app, aid, tok["s2"], {"scene": scene_text("carol")})
    grace = submit(app, aid, tok["s3"], image("grace"))

    got = {k: finished(app, aid, s["id"], tok[k]) for k, s in (("s1", alice), ("s2", carol), ("s3", grace))}
    assert {k: (g["status"], g["score"], g["max_score"]) for k, g in got.items()} == {
        "s1": ("graded", 13.0, 13.0), "s2": ("invalid", 0.0, 13.0), "s3": ("graded", 7.0, 7.0)}  # fmt: skip
    assert [g["counts_as_attempt"] for g in got.values()] == [True, False, True]
    pixels = [t for t in got["s1"]["feedback"]["tests"] if t["test"] == "pixels"][0]
    assert "score" not in pixels and pixels["hidden"] == "shown after the deadline"
    assert "metrics" not in got["s1"]["feedback"]  # they would tell the hidden test's result
    assert got["s2"]["feedback"]["errors"][0]["message"].startswith("invalid JSON")
    left = {k: app.get(f"/api/assignments/{aid}", headers=bearer(t)).json()["submissions_left"] for k, t in tok.items()}
    assert left == {"s1": 2, "s2": 3, "s3": 2, "s4": 3}

    everyone = app.get(f"/api/assignments/{aid}/submissions", headers=TEACHER).json()["submissions"]
    assert sorted(s["student"] for s in everyone) == ["s1", "s2", "s3"]
    mine = app.get(f"/api/assignments/{aid}/submissions", headers=bearer(tok["s1"])).json()["submissions"]
    assert [s["id"] for s in mine] == [alice["id"]] and mine[0]["counts"] is True
    teacher_view = app.get(f"/api/assignments/{aid}/submissions/{alice['id']}", headers=TEACHER).json()
    assert [t for t in teacher_view["feedback"]["tests"] if t["test"] == "pixels"][0]["score"] == 2

    assert grades(app, aid) == [
        {"id": "s1", "name": "Alice A", "score": "13", "max_score": "13", "late": "false", "submissions": "1"},
        {"id": "s2", "name": "Carol C", "score": "", "max_score": "", "late": "", "submissions": "1"},
        {"id": "s3", "name": "Grace G", "score": "7", "max_score": "7", "late": "false", "submissions": "1"},
        {"id": "s4", "name": "Nobody N", "score": "", "max_score": "", "late": "", "submissions": "0"},
    ]
    clock.now = DEADLINE + timedelta(seconds=1)  # the deadline passed (no late cut-off): the pixels test shown
    after = app.get(f"/api/assignments/{aid}/submissions/{alice['id']}", headers=bearer(tok["s1"])).json()
    assert [t for t in after["feedback"]["tests"] if t["test"] == "pixels"][0]["score"] == 2
    assert "metrics" in after["feedback"]
