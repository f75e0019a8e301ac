"""Staff-graded items (server/course/manual.py, server/api/routes/manual.py) on a real server on loopback: a
course with an instructor and two TAs, the statistics tests' small assignment (6 auto points) with two manual
items (creativity 3, lighting 2), a class of three (ann: full marks, bea: 2 points, cid: nothing). The TAs grade
from the queue (the next counting submission, anonymous until the release), bad grades are 422s naming the field;
before the release the student's view, grades.csv and the gradebook have the auto part only, after it both; an
edit that changes a level's points changes the grade; graders dealt evenly see their own. Anonymous grading hides
names from a TA in every view of the assignment until the release; the dashboard's and the statistics' grades count
the manual part (marked not released); each change is an event of the audit trail. Time is the app's clock, never
slept to."""

from __future__ import annotations

import copy
import csv
import io
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import bearer, course_client, wait_for
from tests.support.manual import MANUAL, manual_spec, publish_class
from tests.support.stats import reference

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=2)

spec = manual_spec


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("manual-data"), T0) as c:
        yield c


@pytest.fixture(scope="module")
def cls(app):
    """The course `cs-m` (prof, ta-1, ta-2), the assignment, the roster's tokens and the two graded submissions."""
    assert app.post("/api/courses", json={"id": "cs-m", "name": "Manual"}).status_code == 201
    staff = {}
    for person, role in (("prof", "instructor"), ("ta-1", "ta"), ("ta-2", "ta")):
        r = app.post("/api/courses/cs-m/staff", json={"id": person, "name": person.title(), "role": role})
        assert r.status_code == 201, r.text
        staff[person] = bearer(r.json()["token"])
    roster = "id,name,email\nann,Ann A,\nbea,Bea B,\ncid,Cid C,\n"
    aid, tok, sids = publish_class(app, "/api/assignments?course=cs-m", staff["prof"], DEADLINE.isoformat(), roster)
    return {"aid": aid, "staff": staff, "tok": tok, "sids": sids}


def grades_csv(app, aid: str) -> dict[str, list[str]]:
    rows = list(csv.reader(io.StringIO(app.get(f"/api/assignments/{aid}/grades.csv").text)))
    assert rows[0] == ["id", "name", "score", "max_score", "late", "submissions"]
    return {r[0]: r[2:4] for r in rows[1:]}


def test_manual_a_spec_with_a_bad_manual_item_is_refused_at_its_path(app, cls):
    bad = spec([{**MANUAL[1], "rubric": [{"name": "area light", "points": 5}]}])
    r = app.post("/api/assignments?course=cs-m", json={"spec": bad, "deadline": DEADLINE.isoformat()})
    assert r.status_code == 422
    assert {"path": "spec.manual[0].rubric[0].points",
            "message": "expected points within -2..2 (the item's); got 5"} in r.json()["errors"]  # fmt: skip


def test_manual_queue_grades_release_and_an_edit(app, cls):
    aid, staff, tok, sids = cls["aid"], cls["staff"], cls["tok"], cls["sids"]
    ta1, ta2, prof = staff["ta-1"], staff["ta-2"], staff["prof"]
    assert app.get(f"/api/assignments/{aid}/grading/next", headers=tok["ann"]).status_code == 404  # a student
    assert app.put(f"/api/assignments/{aid}/grading/settings", json={"anonymous": True}, headers=ta1).status_code == 403
    r = app.put(f"/api/assignments/{aid}/grading/settings", json={"anonymous": True}, headers=prof)
    assert r.status_code == 200 and r.json()["anonymous"] is True, r.text

    r = app.get(f"/api/assignments/{aid}/grading/next", headers=ta1)
    assert r.status_code == 200, r.text
    nxt = r.json()
    assert (nxt["submission"], nxt["student"], nxt["label"], nxt["remaining"]) == (sids["ann"], None, "Student 1", 2)
    assert nxt["render"].endswith(f"/submissions/{sids['ann']}/render.png")
    assert nxt["reference"].endswith(".png")
    assert app.get(nxt["render"], headers=ta1).status_code == 200
    assert app.get(nxt["scene"], headers=ta1).json()["objects"] == reference()["objects"]
    assert (nxt["auto"]["score"], nxt["auto"]["max_score"]) == (6.0, 6.0)
    assert nxt["auto"]["feedback"]["tests"]
    assert [i["name"] for i in nxt["items"]] == ["creativity", "lighting"]
    assert nxt["manual"]["points"] is None
    after = app.get(f"/api/assignments/{aid}/grading/next?after={sids['ann']}", headers=ta1).json()
    assert after["submission"] == sids["bea"]  # n: the next one

    put = f"/api/assignments/{aid}/submissions/{sids['ann']}/manual"
    for path, body, item, words in (
        ("item", {"rubric": []}, "colour", "no manual item 'colour'; the items: 'creativity', 'lighting'"),
        ("rubric[1]", {"rubric": ["new objects", "glass"]}, "creativity", "no level 'glass' in the rubric of"),
        ("points", {"rubric": [], "points": 4}, "lighting", "expected points within 0..2 (the item's); got 4"),
        ("grade", {"rubric": [], "grade": 1}, "lighting", ""),
    ):
        r = app.put(f"{put}/{item}", json=body, headers=ta1)
        assert r.status_code == 422, r.text
        assert any(e["path"] == path and words in e["message"] for e in r.json()["errors"]), r.json()
    assert app.put(f"{put}/lighting", json={"rubric": []}, headers=tok["ann"]).status_code == 404

    r = app.put(
        f"{put}/creativity", json={"rubric": ["new objects", "a story"], "comment": "a nice story"}, headers=ta1
    )
    assert r.status_code == 200, r.text
    assert r.json()["manual"]["items"][0] == {
        "name": "creativity", "max_points": 3.0, "points": 2.5, "rubric": ["new objects", "a story"], "override": None,
        "comment": "a nice story", "grader": "ta-1", "graded_at": "2026-12-01T12:00:00Z",
    }  # fmt: skip
    assert app.get(f"/api/assignments/{aid}/grading/next", headers=ta1).json()["submission"] == sids["ann"]  # one left
    r = app.put(f"{put}/lighting", json={"rubric": ["area light", "mood"]}, headers=ta2)  # 3 clamped to 2
    assert r.status_code == 200 and r.json()["manual"]["points"] == 4.5 and r.json()["manual"]["complete"], r.text
    nxt = app.get(f"/api/assignments/{aid}/grading/next", headers=ta2).json()
    assert (nxt["submission"], nxt["label"], nxt["remaining"]) == (sids["bea"], "Student 2", 1)
    r = app.put(f"/api/assignments/{aid}/submissions/{sids['bea']}/manual/creativity",
                json={"rubric": ["copied"], "points": 1, "comment": "override"}, headers=ta2)  # fmt: skip
    assert r.status_code == 200 and r.json()["manual"]["points"] == 1.0, r.text

    # before the release: the auto part only, to the student and in the exports
    view = app.get(f"/api/assignments/{aid}/submissions/{sids['ann']}", headers=tok["ann"]).json()
    assert view["manual"] == {"released": False}
    assert (view["score"], view["total"], view["total_max"]) == (6, 6, 6)
    assert grades_csv(app, aid) == {"ann": ["6", "6"], "bea": ["2", "6"], "cid": ["", ""]}
    book = list(csv.reader(io.StringIO(app.get(f"/api/assignments/{aid}/gradebook.csv").text)))
    assert book[1][5] == "6"
    assert book[2][5] == "6"
    assert app.post(f"/api/assignments/{aid}/release", headers=ta1).status_code == 403
    anonymous_to_tas(app, cls)
    board = app.get(f"/api/assignments/{aid}/dashboard", headers=prof).json()
    assert (board["max_points"], board["released"], board["summary"]["mean"]) == (11, False, 6.75)
    assert [(r["score"], r["manual"], r["total"], r["total_max"], r["points"], r["released"])
            for r in board["students"]] == [(6, 4.5, 10.5, 11, 10.5, False), (2, 1, 3, 11, 3, False),
                                            (None, None, None, None, None, False)]  # fmt: skip
    stats = app.get(f"/api/assignments/{aid}/stats", headers=prof).json()
    assert stats["max_points"] == 11
    assert [b["count"] for b in stats["histogram"]["bins"]][2::7] == [1, 1]

    app.app.state.clock.now = T0 + timedelta(hours=1)
    r = app.post(f"/api/assignments/{aid}/release", headers=prof)
    assert r.status_code == 200 and r.json()["released_at"] == "2026-12-01T13:00:00Z", r.text
    view = app.get(f"/api/assignments/{aid}/submissions/{sids['ann']}", headers=tok["ann"]).json()
    assert (view["score"], view["total"], view["total_max"]) == (6, 10.5, 11)
    assert view["manual"]["released"]
    assert view["manual"]["points"] == 4.5
    assert [(i["points"], i["comment"]) for i in view["manual"]["items"]] == [(2.5, "a nice story"), (2, "")]
    assert "grader" not in view["manual"]["items"][0]  # the student is not told who graded
    assert grades_csv(app, aid) == {"ann": ["10.5", "11"], "bea": ["3", "11"], "cid": ["", ""]}
    book = list(csv.reader(io.StringIO(app.get(f"/api/assignments/{aid}/gradebook.csv").text)))
    assert (book[1][5], book[2][5], book[3][5]) == ("11", "10.5", "3")
    board = app.get(f"/api/assignments/{aid}/dashboard", headers=ta1).json()  # the grades.csv's totals, released
    assert board["released"]
    assert [(r["name"], r["total"], r["total_max"]) for r in board["students"]] == [
        ("Ann A", 10.5, 11),
        ("Bea B", 3, 11),
        ("Cid C", None, None),
    ]
    nxt = app.get(f"/api/assignments/{aid}/grading/submissions/{sids['bea']}", headers=ta1).json()
    assert nxt["student"] == {"id": "bea", "name": "Bea B"}  # anonymous until the release only

    # an edit that changes a level's points changes every grade that chose it
    changed = copy.deepcopy(MANUAL)
    changed[0]["rubric"][1]["points"] = 1
    r = app.put(f"/api/assignments/{aid}", json={"spec": spec(changed), "deadline": DEADLINE.isoformat()}, headers=prof)
    assert r.status_code == 200, r.text
    assert grades_csv(app, aid)["ann"] == ["11", "11"]
    view = app.get(f"/api/assignments/{aid}/submissions/{sids['ann']}", headers=tok["ann"]).json()
    assert view["manual"]["items"][0]["points"] == 3
    assert view["total"] == 11


def anonymous_to_tas(app, cls) -> None:
    """Anonymous grading, not released: a TA sees the queue's labels in the dashboard, a student's detail (asked
    for by label), the submissions list and the similarity report's pairs; the instructor sees names there."""
    aid, staff, sids = cls["aid"], cls["staff"], cls["sids"]
    ta, prof = staff["ta-1"], staff["prof"]
    rows = app.get(f"/api/assignments/{aid}/dashboard", headers=ta).json()["students"]
    assert [(r["id"], r["name"], r["email"]) for r in rows] == [
        (f"Student {i}", f"Student {i}", None) for i in (1, 2, 3)
    ]
    rows = app.get(f"/api/assignments/{aid}/dashboard", headers=prof).json()["students"]
    assert [r["name"] for r in rows] == ["Ann A", "Bea B", "Cid C"]
    r = app.get(f"/api/assignments/{aid}/students/Student 2", headers=ta)
    assert r.status_code == 200, r.text
    detail = r.json()
    assert (detail["name"], detail["email"], detail["counting"], detail["tokens"]["student"]) == (
        "Student 2",
        None,
        sids["bea"],
        "Student 2",
    )
    assert {v["student"] for v in detail["history"]} == {"Student 2"}
    assert app.get(f"/api/assignments/{aid}/students/bea", headers=ta).status_code == 404
    assert app.get(f"/api/assignments/{aid}/students/bea", headers=prof).json()["name"] == "Bea B"
    per = app.get(f"/api/assignments/{aid}/stats", headers=ta).json()["per_student"]
    assert [(r["id"], r["name"]) for r in per] == [(f"Student {i}", f"Student {i}") for i in (1, 2, 3)]
    assert [r["id"] for r in app.get(f"/api/assignments/{aid}/stats", headers=prof).json()["per_student"]] == [
        "ann", "bea", "cid"
    ]  # fmt: skip
    subs = app.get(f"/api/assignments/{aid}/submissions", headers=ta).json()["submissions"]
    assert sorted(v["student"] for v in subs) == ["Student 1", "Student 2"]
    subs = app.get(f"/api/assignments/{aid}/submissions", headers=prof).json()["submissions"]
    assert sorted(v["student"] for v in subs) == ["ann", "bea"]
    assert app.post(f"/api/assignments/{aid}/similarity", headers=prof).status_code == 202
    url = f"/api/assignments/{aid}/similarity"
    wait_for(lambda: app.get(url, headers=prof).json()["status"] == "done", 120, "the similarity report", 0.1)
    pairs = app.get(url, headers=ta).json()["closest"]
    assert [(p["a"], p["b"]) for p in pairs] == [("Student 1", "Student 2")]
    assert [(p["a"], p["b"]) for p in app.get(url, headers=prof).json()["closest"]] == [("ann", "bea")]


def test_manual_graders_dealt_evenly_see_their_own(app, cls):
    aid, staff = cls["aid"], cls["staff"]
    r = app.post(f"/api/assignments/{aid}/grading/assign", json={"graders": ["ta-1", "dean"]}, headers=staff["prof"])
    assert r.status_code == 422 and r.json()["errors"][0]["path"] == "graders[1]", r.text
    assert app.post(f"/api/assignments/{aid}/grading/assign", json={"graders": ["ta-1"]},
                    headers=staff["ta-1"]).status_code == 403  # fmt: skip
    r = app.post(f"/api/assignments/{aid}/grading/assign", json={"graders": ["ta-1", "ta-2"]}, headers=staff["prof"])
    assert r.status_code == 200
    assert r.json() == {"graders": [{"id": "ta-1", "students": 2}, {"id": "ta-2", "students": 1}]}
    # cid hands in now
    sub = app.post(f"/api/assignments/{aid}/submissions", json={"scene": reference()}, headers=cls["tok"]["cid"])
    assert sub.status_code == 202, sub.text
    url = f"/api/assignments/{aid}/submissions/{sub.json()['id']}"
    wait_for(lambda: app.get(url).json()["status"] == "graded", 240, "cid's submission", 0.1)
    # ann (ta-1) is graded; bea (ta-2) lacks her lighting; cid is ta-1's
    nxt = app.get(f"/api/assignments/{aid}/grading/next", headers=staff["ta-2"]).json()
    assert (nxt["submission"], nxt["remaining"]) == (cls["sids"]["bea"], 1)
    r = app.put(f"/api/assignments/{aid}/submissions/{nxt['submission']}/manual/lighting", json={"rubric": ["mood"]},
                headers=staff["ta-2"])  # fmt: skip
    assert r.status_code == 200 and r.json()["manual"]["points"] == 2, r.text
    assert grades_csv(app, aid)["bea"] == ["4", "11"]  # released: a later grade reaches the exports at once
    assert app.get(f"/api/assignments/{aid}/grading/next", headers=staff["ta-2"]).status_code == 204
    assert (
        app.get(f"/api/assignments/{aid}/grading/next", headers=staff["ta-1"]).json()["submission"] == sub.json()["id"]
    )
    assert app.get(f"/api/assignments/{aid}/grading/next?grader=ta-2", headers=staff["ta-1"]).status_code == 204
    state = app.get(f"/api/assignments/{aid}/grading", headers=staff["ta-1"]).json()
    assert (state["released"], state["remaining"], state["max_points"]) == (True, 1, 5)
    assert state["graders"] == [{"id": "ta-1", "students": 2}, {"id": "ta-2", "students": 1}]
    assert [(x["id"], x["role"]) for x in state["staff"]] == [("prof", "instructor"), ("ta-1", "ta"), ("ta-2", "ta")]
    state = app.get(f"/api/assignments/{aid}/grading", headers=staff["ta-2"]).json()
    assert (state["you"], state["remaining"], state["remaining_all"]) == ("ta-2", 0, 1)
    nxt = app.get(f"/api/assignments/{aid}/grading/next?all=true", headers=staff["ta-2"])  # "all": another's too
    assert nxt.status_code == 200 and nxt.json()["submission"] == sub.json()["id"], nxt.text


def test_manual_each_change_is_in_the_audit_trail(app, cls):
    """The changes of the tests above, each an event of the course's trail: the anonymity switched on, each grade
    (before: none, after: its points, levels, override and comment), a grade changed (before and after), the
    release, the edit that re-scored a level, the graders dealt."""
    aid, staff, sids = cls["aid"], cls["staff"], cls["sids"]
    app.app.state.clock.now = T0 + timedelta(hours=2)
    r = app.put(f"/api/assignments/{aid}/submissions/{sids['ann']}/manual/lighting",
                json={"rubric": ["area light"], "comment": "no mood"}, headers=staff["ta-1"])  # fmt: skip
    assert r.status_code == 200, r.text
    r = app.put(f"/api/assignments/{aid}/grading/settings", json={"anonymous": True}, headers=staff["prof"])
    assert r.status_code == 200, r.text  # no change: no event
    r = app.get(f"/api/courses/cs-m/audit?assignment={aid}", headers=staff["prof"])
    assert r.status_code == 200, r.text
    evs = r.json()["events"][::-1]  # oldest first
    manual = [e for e in evs if e["action"].startswith("manual.") or e["action"] == "assignment.release"]
    assert [(e["action"], e["who"]) for e in manual] == [
        ("manual.anonymous", "instructor:prof"),
        ("manual.grade", "ta:ta-1"), ("manual.grade", "ta:ta-2"), ("manual.grade", "ta:ta-2"),
        ("assignment.release", "instructor:prof"),
        ("manual.rescore", "instructor:prof"),
        ("manual.graders", "instructor:prof"),
        ("manual.grade", "ta:ta-2"), ("manual.grade", "ta:ta-1"),
    ]  # fmt: skip
    anonymous, first, _, override, release, rescore, graders, _, changed = manual
    assert (anonymous["before"], anonymous["after"]) == ({"anonymous": False}, {"anonymous": True})
    assert anonymous["target"] == {"course": "cs-m", "assignment": aid}
    assert first["target"] == {"course": "cs-m", "assignment": aid, "student": "ann", "submission": sids["ann"]}
    assert first["before"] is None
    assert (first["after"] == {
        "item": "creativity", "points": 2.5, "rubric": ["new objects", "a story"], "override": None,
        "comment": "a nice story", "grader": "ta-1",
    })  # fmt: skip
    assert (override["after"]["points"], override["after"]["override"]) == (1, 1)
    assert (release["at"], release["before"], release["after"]) == (
        "2026-12-01T13:00:00Z",
        {"released_at": None},
        {"released_at": "2026-12-01T13:00:00Z"},
    )
    assert (rescore["before"], rescore["after"]) == (
        {"points": {"creativity: a story": 0.5}},
        {"points": {"creativity: a story": 1}, "grades": 1},
    )
    assert graders["before"] == {"graders": None}
    assert graders["after"] == {"graders": {"ann": "ta-1", "bea": "ta-2", "cid": "ta-1"}}
    assert changed["at"] == "2026-12-01T14:00:00Z"
    assert changed["target"]["student"] == "ann"
    assert changed["before"] == {
        "item": "lighting", "points": 2, "rubric": ["area light", "mood"], "override": None, "comment": "",
        "grader": "ta-2",
    }  # fmt: skip
    assert changed["after"] == {
        "item": "lighting", "points": 2, "rubric": ["area light"], "override": None, "comment": "no mood",
        "grader": "ta-1",
    }  # fmt: skip
    mine = app.get("/api/courses/cs-m/audit?student=bea", headers=staff["prof"]).json()["events"]
    assert {e["action"] for e in mine} >= {"manual.grade"}
    assert all(e["target"].get("student") == "bea" for e in mine)
