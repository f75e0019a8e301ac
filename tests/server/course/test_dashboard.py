"""The instructor's dashboard routes (server/course/dashboard.py, server/api/routes/dashboard.py):
GET /api/assignments/{id}/dashboard, the roster with each student's state and counting score in one answer,
and GET /api/assignments/{id}/students/{student}, one student's history. A small assignment (the example's
reference scene at 32 x 24, so that its reference renders in a second or two) is published; students submit
a valid scene, an invalid one, a late image and nothing; each student's state, score, submissions, deadline
and self-declared mark are read back, and a student's token gets the 404 of an unknown id on both routes.
Time is the app's clock (`app.state.clock`), moved past the deadline, never slept to."""

from __future__ import annotations

import base64
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import Clock, bearer, course_client, student_token, wait_for
from tests.support.dashboard import bad_scene, good_scene, small_spec

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=2)


def good_image(client, aid: str) -> dict:
    """The reference's own picture, as a student's PNG (the instructor fetches it once it is rendered)."""
    png = wait_for(
        lambda: (r := client.get(f"/api/assignments/{aid}/reference.png")).status_code == 200 and r.content,
        120,
        "the reference image",
    )
    return {"image": base64.b64encode(png).decode(), "format": "png"}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    data = tmp_path_factory.mktemp("dashboard-data")
    with course_client(data, T0) as c:
        yield c


def graded(client, aid: str, sid: str) -> dict:
    url = f"/api/assignments/{aid}/submissions/{sid}"
    return wait_for(
        lambda: (s := client.get(url).json())["status"] in ("graded", "invalid", "failed") and s,
        240,
        f"submission {sid} graded",
        interval=0.1,
    )


def test_dashboard_the_roster_against_each_students_state_and_score(app):
    clock = app.app.state.clock
    late_until = (DEADLINE + timedelta(days=1)).isoformat()
    body = {"spec": small_spec(), "deadline": DEADLINE.isoformat(), "late_until": late_until, "late_penalty": 0.5,
            "open": True}  # fmt: skip
    r = app.post("/api/assignments", json=body)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    text = "id,name,email\nann,Ann A,ann@x.edu\nbea,Bea B,bea@x.edu\ncid,Cid C,\ndan,Dan D,dan@x.edu\n"
    r = app.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv"})
    tok = {s["id"]: s["token"] for s in r.json()["students"]}
    joined = app.post(f"/api/assignments/{aid}/join", json={"name": "Zoë Z"}, headers={}).json()

    board = app.get(f"/api/assignments/{aid}/dashboard").json()
    assert [s["id"] for s in board["students"]] == sorted(["ann", "bea", "cid", "dan", joined["id"]])
    assert {s["state"] for s in board["students"]} == {"none"}
    assert board["summary"] == {
        "students": 5, "submitted": 0, "not_submitted": 5, "waiting": 0, "late": 0,
        "graded": 0, "invalid": 0, "failed": 0, "mean": None, "median": None,
    }  # fmt: skip
    assert board["max_points"] == 6
    assert board["name"] == "HW 0: a small glass ball"

    ann = app.post(f"/api/assignments/{aid}/submissions", json={"scene": good_scene()}, headers=bearer(tok["ann"]))
    bea = app.post(f"/api/assignments/{aid}/submissions", json={"scene": bad_scene()}, headers=bearer(tok["bea"]))
    assert ann.status_code == bea.status_code == 202, (ann.text, bea.text)
    seen = {s["id"]: s for s in app.get(f"/api/assignments/{aid}/dashboard").json()["students"]}
    assert seen["ann"]["state"] in ("submitted", "graded")
    assert seen["ann"]["submissions"] == 1
    graded(app, aid, ann.json()["id"])
    graded(app, aid, bea.json()["id"])

    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "dan", "deadline": "2026-12-05T12:00:00Z"})
    assert r.status_code == 200, r.text
    clock.now = DEADLINE + timedelta(hours=1)  # past the deadline: cid's image is late (half its points)
    late = app.post(f"/api/assignments/{aid}/submissions", json=good_image(app, aid), headers=bearer(tok["cid"]))
    assert late.status_code == 202 and late.json()["late"] is True, late.text
    graded(app, aid, late.json()["id"])

    board = app.get(f"/api/assignments/{aid}/dashboard").json()
    rows = {s["id"]: s for s in board["students"]}
    got = {
        k: (r["state"], r["score"], r["max_score"], r["points"], r["late"], r["submissions"]) for k, r in rows.items()
    }
    assert got == {
        "ann": ("graded", 6.0, 6.0, 6.0, False, 1),
        "bea": ("invalid", None, None, None, False, 1),
        "cid": ("graded", 2.0, 4.0, 3.0, True, 1),  # 4 of 4 for an image, halved: 2 of 4 is 3 of the spec's 6
        "dan": ("none", None, None, None, False, 0),
        joined["id"]: ("none", None, None, None, False, 0),
    }
    assert rows["ann"]["counting"] == ann.json()["id"]
    assert rows["bea"]["counting"] is None
    assert (rows["dan"]["deadline"], rows["dan"]["extended"]) == ("2026-12-05T12:00:00Z", True)
    assert (rows["ann"]["deadline"], rows["ann"]["extended"]) == ("2026-12-03T12:00:00Z", False)
    assert [r["self_declared"] for r in rows.values()].count(True) == 1
    assert rows[joined["id"]]["self_declared"]
    assert rows[joined["id"]]["name"] == "Zoë Z"
    assert rows["ann"]["email"] == "ann@x.edu"
    s = board["summary"]
    assert (s["students"], s["submitted"], s["not_submitted"], s["graded"], s["invalid"], s["late"]) == (
        5,
        3,
        2,
        2,
        1,
        1,
    )
    assert (s["mean"], s["median"], s["waiting"]) == (4.5, 4.5, 0)
    assert board["now"] == "2026-12-03T13:00:00Z"


def test_dashboard_a_students_history_with_feedback_and_pictures(app):
    app.app.state.clock = Clock(T0)
    body = {"spec": small_spec(), "deadline": DEADLINE.isoformat(), "counts": "best"}
    aid = app.post("/api/assignments", json=body).json()["id"]
    r = app.post(
        f"/api/assignments/{aid}/roster", content="id,name,email\nann,Ann A,\n", headers={"Content-Type": "text/csv"}
    )
    tok = r.json()["students"][0]["token"]
    bad = app.post(f"/api/assignments/{aid}/submissions", json={"scene": bad_scene()}, headers=bearer(tok)).json()
    good = app.post(f"/api/assignments/{aid}/submissions", json={"scene": good_scene()}, headers=bearer(tok)).json()
    graded(app, aid, bad["id"])
    graded(app, aid, good["id"])

    d = app.get(f"/api/assignments/{aid}/students/ann")
    assert d.status_code == 200, d.text
    d = d.json()
    assert (d["id"], d["state"], d["score"], d["counting"]) == ("ann", "graded", 6.0, good["id"])
    assert [(x["id"], x["status"], x["counts"]) for x in d["history"]] == [
        (bad["id"], "invalid", False),
        (good["id"], "graded", True),
    ]
    first, second = d["history"]
    assert any("radius" in e["path"] for e in first["feedback"]["errors"])
    assert [t["test"] for t in second["feedback"]["tests"]] == [
        "validity",
        "a glass object",
        "an area light",
        "psnr",
        "pixels",
    ]
    assert all("score" in t and "output" in t for t in second["feedback"]["tests"])  # the instructor sees all
    assert set(second["files"]) == {"render.png", "error_map.png", "rejected.png", "reference.png"}
    png = app.get(second["files"]["error_map.png"])
    assert png.status_code == 200
    assert png.content[:4] == b"\x89PNG"

    r = app.get(f"/api/assignments/{aid}/students/nobody")
    assert r.status_code == 404
    assert r.json()["errors"][0]["path"] == "student"


def test_dashboard_is_the_instructors_only(app):
    """A student's token (of this assignment or none) gets the 404 of an unknown id; no instructor token: 401."""
    body = {"spec": small_spec(), "deadline": DEADLINE.isoformat()}
    aid = app.post("/api/assignments", json=body).json()["id"]
    r = app.post(
        f"/api/assignments/{aid}/roster", content="id,name,email\nann,Ann A,\n", headers={"Content-Type": "text/csv"}
    )
    tok = r.json()["students"][0]["token"]
    for path in (f"/api/assignments/{aid}/dashboard", f"/api/assignments/{aid}/students/ann"):
        r = app.get(path, headers=bearer(tok))
        assert r.status_code == 404 and r.json()["errors"][0]["path"] == "id", r.text
        assert app.get(path, headers=bearer(student_token())).status_code == 401
        assert app.get(path).status_code == 200
    r = app.get(f"/api/assignments/{'0' * 32}/dashboard")
    assert r.status_code == 404
