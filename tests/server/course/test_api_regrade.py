"""Regrade requests (server/course/regrade.py, server/api/routes/regrade.py) on a real server on loopback: a course
with an instructor and a TA, the statistics tests' small assignment (6 auto points: validity 1, 'a glass object'
1, 'an area light' 1, psnr 1, pixels 2 shown after the deadline) with a staff-graded item (creativity, 3), a
class of three: ann (full marks), bea (a first submission with the glass, then her counting one without: 2
points), cid (nothing). Each refusal names its field; a TA accepts a test's regrade with points (the grades CSV
moves), answers it again (declined: nothing but the request changes), the instructor accepts a manual item's; the
history and the audit trail keep every change; a student sees only their own. Time is the app's clock (the
regrade deadline: a week after the late cut-off), never slept to."""

from __future__ import annotations

import csv
import io
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import bearer, course_client, wait_for
from tests.support.stats import red, reference, small_spec

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=2)
MANUAL = [{"name": "creativity", "points": 3, "rubric": [{"name": "new objects", "points": 2}]}]
GLASS = "a glass object"


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("regrade-data"), T0) as c:
        yield c


@pytest.fixture(scope="module")
def cls(app):
    """The course `cs-r` (prof, ta-1), the assignment, the students' tokens, bea's two submissions and ann's."""
    assert app.post("/api/courses", json={"id": "cs-r", "name": "Regrades"}).status_code == 201
    staff = {}
    for person, role in (("prof", "instructor"), ("ta-1", "ta")):
        r = app.post("/api/courses/cs-r/staff", json={"id": person, "name": person.title(), "role": role})
        assert r.status_code == 201, r.text
        staff[person] = bearer(r.json()["token"])
    body = {"spec": {**small_spec(), "manual": MANUAL}, "deadline": DEADLINE.isoformat(),
            "feedback": {"tests": {"pixels": "after_deadline"}}}  # fmt: skip
    r = app.post("/api/assignments?course=cs-r", json=body, headers=staff["prof"])
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    roster = "id,name,email\nann,Ann A,\nbea,Bea B,\ncid,Cid C,\n"
    r = app.post(
        f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv", **staff["prof"]}
    )
    assert r.status_code == 200, r.text
    tok = {s["id"]: bearer(s["token"]) for s in r.json()["students"]}
    sids = {}
    for key, student, scene in (("ann", "ann", reference()), ("bea-1", "bea", red(glass=True)),
                                ("bea", "bea", red(glass=False))):  # fmt: skip
        app.app.state.clock.now += timedelta(minutes=1)
        r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=tok[student])
        assert r.status_code == 202, r.text
        sids[key] = r.json()["id"]
    for sid in sids.values():
        url = f"/api/assignments/{aid}/submissions/{sid}"
        wait_for(lambda u=url: app.get(u).json()["status"] in ("graded", "invalid", "failed"), 240, sid, 0.1)
    return {"aid": aid, "staff": staff, "tok": tok, "sids": sids}


def grades_csv(app, aid: str) -> dict[str, list[str]]:
    rows = list(csv.reader(io.StringIO(app.get(f"/api/assignments/{aid}/grades.csv").text)))
    return {r[0]: r[2:4] for r in rows[1:]}


def ask(app, cls, who: str, item: str, reason: str = "My ball is glass: kt 0.9", sid: str | None = None):
    sid = sid or cls["sids"][who]
    url = f"/api/assignments/{cls['aid']}/submissions/{sid}/regrade-requests"
    return app.post(url, json={"item": item, "reason": reason}, headers=cls["tok"][who.split("-")[0]])


def refusal(r, status: int, path: str) -> str:
    assert r.status_code == status, r.text
    err = r.json()["errors"][0]
    assert err["path"] == path, r.text
    return err["message"]


def audit(app, action: str) -> list[dict]:
    events = app.get("/api/courses/cs-r/audit", params={"limit": 500}).json()["events"]
    return [e for e in events if e["action"] == action]


def test_regrade_each_refusal_names_its_field(app, cls):
    aid, sids = cls["aid"], cls["sids"]
    assert "'a glass object'" in refusal(ask(app, cls, "bea", "elegance"), 422, "item")
    assert "not shown to you yet" in refusal(ask(app, cls, "bea", "pixels"), 403, "item")  # after the deadline only
    assert "not released" in refusal(ask(app, cls, "bea", "creativity"), 403, "item")
    assert "grade" in refusal(ask(app, cls, "bea-1", GLASS, sid=sids["bea-1"]), 409, "sid")  # not the counting one
    refusal(ask(app, cls, "bea", GLASS, reason=""), 422, "reason")
    refusal(ask(app, cls, "bea", GLASS, reason="x" * 2001), 422, "reason")
    refusal(ask(app, cls, "ann", GLASS, sid=sids["bea"]), 404, "sid")  # another student's submission
    url = f"/api/assignments/{aid}/submissions/{sids['bea']}/regrade-requests"
    refusal(app.post(url, json={"item": GLASS, "reason": "staff"}, headers=cls["staff"]["ta-1"]), 403, "role")
    # a regrade deadline before the deadline is refused at its field
    bad = {"spec": small_spec(), "deadline": DEADLINE.isoformat(), "regrade_deadline": T0.isoformat()}
    r = app.post("/api/assignments?course=cs-r", json=bad, headers=cls["staff"]["prof"])
    assert r.status_code == 422 and any(e["path"] == "regrade_deadline" for e in r.json()["errors"]), r.text
    assert app.get(f"/api/assignments/{aid}/regrade-requests").json()["requests"] == []  # nothing was kept


def test_regrade_a_ta_accepts_a_test_then_declines_it_each_change_kept(app, cls):
    aid, sids, tok, ta = cls["aid"], cls["sids"], cls["tok"], cls["staff"]["ta-1"]
    app.put(f"/api/assignments/{aid}/grading/settings", json={"anonymous": True}, headers=cls["staff"]["prof"])
    assert grades_csv(app, aid)["bea"] == ["2", "6"]
    r = ask(app, cls, "bea", GLASS)
    assert r.status_code == 201, r.text
    req = r.json()
    assert (req["item"], req["kind"], req["status"], req["points"], req["max_points"]) == (GLASS, "test", "open", 0, 1)
    assert "a request about 'a glass object'" in refusal(ask(app, cls, "bea", GLASS), 409, "item")  # one open at once

    # the queue: staff see it (anonymous: no name), a student only their own, ann none of bea's
    q = app.get(f"/api/assignments/{aid}/regrade-requests", headers=ta).json()["requests"]
    assert [(x["id"], x["student"], x["label"], x["reason"]) for x in q] == [
        (req["id"], None, "Student 2", "My ball is glass: kt 0.9")
    ]
    assert app.get(f"/api/assignments/{aid}/regrade-requests", headers=tok["ann"]).json()["requests"] == []
    mine = app.get(f"/api/assignments/{aid}/regrade-requests", headers=tok["bea"]).json()
    assert [x["id"] for x in mine["requests"]] == [req["id"]]
    assert "student" not in mine["requests"][0]
    assert mine["regrade_deadline"] == "2026-12-10T12:00:00Z"  # a week after the deadline (no late cut-off)
    assert mine["regrade_open"] is True
    url = f"/api/assignments/{aid}/submissions/{sids['bea']}/regrade-requests/{req['id']}"
    for student in ("ann", "bea"):  # a student cannot answer (their own or another's): the unknown id's 404
        assert app.put(url, json={"status": "accepted", "reply": "mine"}, headers=tok[student]).status_code == 404

    # bad answers name their field
    refusal(app.put(url, json={"status": "accepted", "reply": "ok", "points": 2}, headers=ta), 422, "points")
    refusal(app.put(url, json={"status": "declined", "reply": "no", "points": 1}, headers=ta), 422, "points")
    refusal(app.put(url, json={"status": "maybe", "reply": "?"}, headers=ta), 422, "status")
    refusal(app.put(url, json={"status": "accepted", "reply": ""}, headers=ta), 422, "reply")

    # the TA accepts with the point: the grade, the view and the export move
    app.app.state.clock.now = T0 + timedelta(hours=3)
    r = app.put(url, json={"status": "accepted", "reply": "Right: the kt counts.", "points": 1}, headers=ta)
    assert r.status_code == 200, r.text
    assert (r.json()["status"], r.json()["points"], r.json()["answered_by"]) == ("accepted", 1, "ta:ta-1")
    assert grades_csv(app, aid)["bea"] == ["3", "6"]
    view = app.get(f"/api/assignments/{aid}/submissions/{sids['bea']}", headers=tok["bea"]).json()
    glass = next(t for t in view["feedback"]["tests"] if t["test"] == GLASS)
    assert (view["score"], glass["score"], glass["regraded_from"]) == (None, 1, 0)  # the score: after the deadline
    assert app.get(f"/api/assignments/{aid}/submissions/{sids['bea']}", headers=ta).json()["score"] == 3

    # answered again, declined: nothing but the request changes; every change kept
    app.app.state.clock.now = T0 + timedelta(hours=4)
    r = app.put(url, json={"status": "declined", "reply": "On a second look: no."}, headers=ta)
    assert r.status_code == 200 and r.json()["status"] == "declined", r.text
    assert grades_csv(app, aid)["bea"] == ["3", "6"]
    mine = app.get(f"/api/assignments/{aid}/regrade-requests", headers=tok["bea"]).json()["requests"][0]
    assert mine["reply"] == "On a second look: no."
    history = [(e["kind"], e["status"], e["at"], e.get("points")) for e in mine["history"]]
    assert history == [
        ("request", "open", "2026-12-01T12:03:00Z", 0),
        ("answer", "accepted", "2026-12-01T15:00:00Z", 1),
        ("answer", "declined", "2026-12-01T16:00:00Z", None),
    ]
    asked, answers = audit(app, "regrade.request"), audit(app, "regrade.answer")
    assert [e["who"] for e in asked] == ["student:bea"]
    assert asked[0]["target"]["submission"] == sids["bea"]
    assert [(e["who"], e["after"]["status"]) for e in answers] == [("ta:ta-1", "declined"), ("ta:ta-1", "accepted")]
    assert (answers[1]["before"]["item_points"], answers[1]["after"]["item_points"]) == (0, 1)
    assert answers[1]["why"] == "Right: the kt counts."
    # the queue: open first, then by status filter
    assert app.get(f"/api/assignments/{aid}/regrade-requests?status=open", headers=ta).json()["requests"] == []
    refusal(app.get(f"/api/assignments/{aid}/regrade-requests?status=done", headers=ta), 422, "status")


def test_regrade_a_manual_item_after_the_release_moves_the_total(app, cls):
    aid, sids, prof = cls["aid"], cls["sids"], cls["staff"]["prof"]
    assert app.post(f"/api/assignments/{aid}/release", headers=prof).status_code == 200
    before = grades_csv(app, aid)["bea"]
    assert before == ["3", "9"]  # the regraded auto part, the manual part not graded: 0 of 3
    r = ask(app, cls, "bea", "creativity", reason="I added three new objects")
    assert r.status_code == 201 and r.json()["kind"] == "manual", r.text
    q = app.get(f"/api/assignments/{aid}/regrade-requests", headers=prof).json()["requests"]
    assert q[0]["item"] == "creativity"
    assert q[0]["status"] == "open"  # open first
    assert q[0]["student"] == {"id": "bea", "name": "Bea B"}  # released: names shown
    url = q[0]["url"]
    r = app.put(url, json={"status": "accepted", "reply": "Yes, they are new.", "points": 2}, headers=prof)
    assert r.status_code == 200 and r.json()["points"] == 2, r.text
    assert grades_csv(app, aid)["bea"] == ["5", "9"]
    view = app.get(f"/api/assignments/{aid}/submissions/{sids['bea']}", headers=cls["tok"]["bea"]).json()
    assert view["manual"]["items"][0]["points"] == 2
    assert view["total"] is None  # the score: after the deadline


def test_regrade_after_the_deadline_a_hidden_test_opens_then_the_regrade_deadline_closes(app, cls):
    app.app.state.clock.now = DEADLINE + timedelta(minutes=1)
    r = ask(app, cls, "bea", "pixels", reason="The sky colour was asked for")
    assert r.status_code == 201, r.text  # shown after the deadline: may be asked about now
    view = app.get(f"/api/assignments/{cls['aid']}/submissions/{cls['sids']['bea']}", headers=cls["tok"]["bea"])
    assert (view.json()["score"], view.json()["total"]) == (3, 5)  # the regraded test and manual item, shown now
    app.app.state.clock.now = DEADLINE + timedelta(days=7, seconds=1)
    message = refusal(ask(app, cls, "bea", "psnr"), 403, "regrade_deadline")
    assert "2026-12-10T12:00:00Z" in message
    mine = app.get(f"/api/assignments/{cls['aid']}/regrade-requests", headers=cls["tok"]["bea"]).json()
    assert mine["regrade_open"] is False
    assert len(mine["requests"]) == 3  # her requests and answers stay readable
