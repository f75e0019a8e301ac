"""The course's audit trail (server/course/audit.py, server/api/routes/audit.py): GET /api/courses/{cid}/audit and
audit.csv on a real server on loopback. Each change there is today (staff added, a publish, the roster's students
added, changed, enrolled and removed, links re-issued, an extension, an edit with its regrade, a regrade) is an
event with who made it, when (the app's clock, moved between changes, never slept to), what it was before and
after, and why; filtered by student and assignment, paged, as CSV with formula-safe cells. A student and another
course's staff get the 404 of an unknown course. A change that fails leaves no event, and an event that cannot be
written undoes its change (one transaction). No render is needed (workers=0)."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
from datetime import UTC, datetime, timedelta

import pytest

from server.core.db import Transaction
from server.course.audit import MAX_LIMIT, By, Target
from tests.support.api import INSTRUCTOR, bearer, course_client
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
ADMIN = bearer(INSTRUCTOR)
CSV = {"Content-Type": "text/csv"}


def spec() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def body(**policy) -> dict:
    return {"spec": spec(), "deadline": (T0 + timedelta(days=2)).isoformat(), **policy}


def z(t: datetime) -> str:
    return t.isoformat().replace("+00:00", "Z")


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("audit-data"), T0, workers=0) as c:
        yield c


@pytest.fixture(scope="module")
def course(app):
    """Course au1 (instructor prof, TA ta) and au2 (instructor other), an assignment of au1 with a roster of
    three and one submission, each change made at its own minute: the tokens, the assignment's id and the times."""
    clock = app.app.state.clock
    at = {}

    def tick(name: str, minutes: int) -> None:
        at[name] = clock.now = T0 + timedelta(minutes=minutes)

    tok = {}
    for cid in ("au1", "au2"):
        assert app.post("/api/courses", json={"id": cid, "name": cid}, headers=ADMIN).status_code == 201
    tick("staff", 1)
    for cid, person, role in (("au1", "prof", "instructor"), ("au1", "ta", "ta"), ("au2", "other", "instructor")):
        r = app.post(f"/api/courses/{cid}/staff", json={"id": person, "role": role}, headers=ADMIN)
        assert r.status_code == 201, r.text
        tok[person] = bearer(r.json()["token"])
    tick("publish", 2)
    r = app.post("/api/courses/au1/assignments", json=body(), headers=tok["prof"])
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    tick("roster", 3)
    roster = 'id,name,email\ns1,Ann A,a@x\ns2,"=HYPERLINK(""http://x/"")",\n'
    r = app.post("/api/courses/au1/roster", content=roster, headers={**CSV, **tok["prof"]})
    assert r.status_code == 200, r.text
    tok.update({s["id"]: bearer(s["token"]) for s in r.json()["students"]})
    tick("roster2", 4)  # s1 renamed, s3 new on the assignment's roster only
    r = app.post(
        f"/api/assignments/{aid}/roster",
        content="id,name,email\ns1,Ann B,a@x\ns3,Cy,\n",
        headers={**CSV, **tok["prof"]},
    )
    assert r.status_code == 200, r.text
    tok["s3"] = bearer(r.json()["students"][1]["token"])
    tick("submit", 5)
    scene = json.loads((EXAMPLE / "reference.json").read_text())
    r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=tok["s1"])
    assert r.status_code == 202, r.text
    tick("extension", 6)
    due = T0 + timedelta(days=3)
    r = app.post(
        f"/api/assignments/{aid}/extensions",
        json={"student": "s1", "deadline": due.isoformat(), "why": "=ill, a doctor's note"},
        headers=tok["ta"],
    )
    assert r.status_code == 200, r.text
    tick("edit", 7)
    r = app.put(
        f"/api/assignments/{aid}?regrade=true&why=typo",
        json=body(late_penalty=0.5, late_until=(T0 + timedelta(days=4)).isoformat()),
        headers=tok["prof"],
    )
    assert r.status_code == 200, r.text
    tick("regrade", 8)
    assert app.post(f"/api/assignments/{aid}/regrade?why=a grading fix", headers=tok["ta"]).status_code == 200
    tick("link", 9)
    assert app.post(f"/api/assignments/{aid}/students/s2/link", headers=tok["prof"]).status_code == 200
    tick("remove", 10)
    assert app.delete("/api/courses/au1/students/s3?why=dropped", headers=tok["prof"]).status_code == 200
    tick("staff2", 11)  # a TA added, their link renewed, removed: by the instructor
    r = app.post("/api/courses/au1/staff", json={"id": "gone", "name": "Gone", "role": "ta"}, headers=tok["prof"])
    assert r.status_code == 201, r.text
    assert app.post("/api/courses/au1/staff/gone/link?renew=true", headers=tok["prof"]).status_code == 200
    assert app.delete("/api/courses/au1/staff/gone", headers=tok["prof"]).status_code == 200
    return tok, aid, at


def events(app, tok, **params) -> list[dict]:
    r = app.get("/api/courses/au1/audit", params=params, headers=tok)
    assert r.status_code == 200, r.text
    return r.json()["events"]


def one(evs: list[dict], action: str, **target) -> dict:
    found = [e for e in evs if e["action"] == action and all(e["target"].get(k) == v for k, v in target.items())]
    assert len(found) == 1, (action, target, evs)
    return found[0]


def test_audit_each_change_is_an_event_with_who_when_before_after_and_why(app, course):
    tok, aid, at = course
    evs = events(app, tok["prof"], limit=500)
    assert [e["id"] for e in evs] == sorted((e["id"] for e in evs), reverse=True)  # newest first
    assert all(set(e) >= {"at", "who", "action", "target", "before", "after", "why"} for e in evs)

    e = one(evs, "staff.add", staff="ta")
    assert (e["who"], e["at"], e["before"]) == ("admin", z(at["staff"]), None)
    assert e["after"] == {"name": "ta", "email": "", "role": "ta"}
    assert e["target"] == {"course": "au1", "staff": "ta"}
    assert not [x for x in evs if x["target"].get("staff") == "other"]  # another course's

    e = one(evs, "publish", assignment=aid)
    assert (e["who"], e["at"], e["before"]) == ("instructor:prof", z(at["publish"]), None)
    assert e["after"]["version"] == 1 and e["after"]["policy"]["deadline"] == z(T0 + timedelta(days=2))

    e = one(evs, "student.add", student="s2")
    assert (e["who"], e["at"], e["why"]) == ("instructor:prof", z(at["roster"]), "the course's roster CSV")
    assert e["after"] == {"name": '=HYPERLINK("http://x/")', "email": "", "every": True}
    e = one(evs, "student.change", student="s1")
    assert e["before"] == {"name": "Ann A", "email": "a@x", "every": True}
    assert e["after"] == {"name": "Ann B", "email": "a@x", "every": True} and e["at"] == z(at["roster2"])
    e = one(evs, "student.add", student="s3")
    assert e["target"] == {"course": "au1", "assignment": aid, "student": "s3"}
    assert e["before"] is None

    e = one(evs, "extension", student="s1")
    assert (e["who"], e["at"], e["why"]) == ("ta:ta", z(at["extension"]), "=ill, a doctor's note")
    assert e["before"] == {"deadline": None} and e["after"] == {"deadline": z(T0 + timedelta(days=3))}
    assert e["target"] == {"course": "au1", "assignment": aid, "student": "s1"}

    e = one(evs, "edit", assignment=aid)
    assert (e["who"], e["at"], e["why"]) == ("instructor:prof", z(at["edit"]), "typo")
    assert e["before"] == {"version": 1, "policy": {"late_penalty": 0.0, "late_until": None}}
    assert e["after"] == {
        "version": 2,
        "policy": {"late_penalty": 0.5, "late_until": z(T0 + timedelta(days=4))},
        "spec_changed": False,
    }
    regrades = sorted((x for x in evs if x["action"] == "regrade"), key=lambda x: x["id"])
    assert [(x["who"], x["at"], x["why"]) for x in regrades] == [
        ("instructor:prof", z(at["edit"]), "typo"),
        ("ta:ta", z(at["regrade"]), "a grading fix"),
    ]
    assert [(x["before"], x["after"]) for x in regrades] == [
        ({"versions": {"1": 1}}, {"version": 2, "submissions": 1}),
        ({"versions": {"2": 1}}, {"version": 3, "submissions": 1}),
    ]
    assert app.get(f"/api/assignments/{aid}", headers=tok["prof"]).json()["version"] == 3  # each event's change

    e = one(evs, "link.renew", student="s2")
    assert (e["before"], e["after"], e["at"]) == ({"link": 0}, {"link": 1}, z(at["link"]))
    assert "token" not in json.dumps(e)
    gone = [
        (x["action"], x["who"], x["at"], x["before"], x["after"]) for x in evs if x["target"].get("staff") == "gone"
    ]
    assert gone[::-1] == [
        ("staff.add", "instructor:prof", z(at["staff2"]), None, {"name": "Gone", "email": "", "role": "ta"}),
        ("link.renew", "instructor:prof", z(at["staff2"]), {"link": 0}, {"link": 1}),
        ("staff.remove", "instructor:prof", z(at["staff2"]), {"name": "Gone", "email": "", "role": "ta"}, None),
    ]
    e = one(evs, "student.remove", student="s3")
    assert (e["before"], e["after"], e["why"]) == ({"name": "Cy", "email": "", "every": False}, None, "dropped")


def test_audit_filters_by_student_and_assignment_and_pages_with_a_bounded_limit(app, course):
    tok, aid, _ = course
    mine = events(app, tok["ta"], student="s1")  # a TA reads it too
    assert {e["action"] for e in mine} == {"student.add", "student.change", "extension"}
    assert all(e["target"]["student"] == "s1" for e in mine)
    of = events(app, tok["prof"], assignment=aid)
    assert {e["action"] for e in of} == {"publish", "student.add", "extension", "edit", "regrade"}
    assert events(app, tok["prof"], assignment=aid, student="s1") == [
        e for e in of if e["target"].get("student") == "s1"
    ]
    assert events(app, tok["prof"], student="nobody") == []

    whole = events(app, tok["prof"], limit=500)
    pages, before = [], None
    for _ in range(len(whole)):  # bounded: one event a page at least
        r = app.get("/api/courses/au1/audit", params={"limit": 3, **({"before": before} if before else {})})
        assert r.status_code == 200, r.text
        pages += r.json()["events"]
        assert len(r.json()["events"]) <= 3
        before = r.json()["next"]
        if before is None:
            break
    assert pages == whole
    for bad in ({"limit": 0}, {"limit": 501}, {"before": "x"}, {"format": "xml"}):
        r = app.get("/api/courses/au1/audit", params=bad)
        assert r.status_code == 422 and r.json()["errors"][0]["path"].endswith(next(iter(bad))), r.text


def test_audit_csv_is_quoted_and_formula_safe(app, course):
    tok, aid, _ = course
    r = app.get("/api/courses/au1/audit.csv", headers=tok["prof"])
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    assert r.headers["cache-control"] == "no-store"
    assert "audit.csv" in r.headers["content-disposition"]
    assert app.get("/api/courses/au1/audit?format=csv", headers=tok["prof"]).text == r.text
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert list(rows[0]) == ["id", "at", "who", "action", "course", "assignment", "student", "target", "before",
                             "after", "why"]  # fmt: skip
    assert [int(x["id"]) for x in rows] == [e["id"] for e in events(app, tok["prof"], limit=500)]
    ext = next(x for x in rows if x["action"] == "extension")
    assert ext["why"] == "'=ill, a doctor's note"  # no formula runs
    assert (ext["student"], ext["assignment"], json.loads(ext["before"])) == ("s1", aid, {"deadline": None})
    assert "\"'=ill, a doctor's note\"" in r.text  # the comma's cell quoted
    added = next(x for x in rows if x["action"] == "student.add" and x["student"] == "s2")
    assert json.loads(added["after"])["name"] == '=HYPERLINK("http://x/")'  # a JSON text: starts with {
    only = list(csv.DictReader(io.StringIO(app.get("/api/courses/au1/audit.csv?student=s3").text)))
    assert {x["action"] for x in only} == {"student.add", "student.remove"}


def test_audit_a_student_and_another_courses_staff_are_refused(app, course):
    tok, _, _ = course
    gone = app.get("/api/courses/nope/audit", headers=tok["prof"])
    assert gone.status_code == 404
    for who in ("s1", "other"):
        for url in ("/api/courses/au1/audit", "/api/courses/au1/audit.csv", "/api/courses/au1/audit?format=csv"):
            r = app.get(url, headers=tok[who])
            assert r.status_code == 404 and r.json()["errors"][0]["path"] == "course", (who, url, r.text)
            assert "events" not in r.text
            assert "s1" not in r.text
    assert app.get("/api/courses/au1/audit", headers=bearer("unknown-token")).status_code in (401, 403)
    assert app.get("/api/courses/au2/audit", headers=tok["other"]).json()["events"][0]["action"] == "staff.add"


def test_audit_a_failed_change_leaves_no_event_and_no_event_is_kept_without_its_change(app, course):
    tok, aid, _ = course
    count = len(events(app, tok["prof"], limit=500))
    refused = [
        app.post(f"/api/assignments/{aid}/extensions", json={"student": "zz", "deadline": None}, headers=tok["ta"]),
        app.post("/api/courses/au1/assignments", json=body(), headers=tok["ta"]),  # a TA may not publish
        app.post("/api/courses/au1/roster", content="id,name,email\nbad id,X,\n", headers={**CSV, **tok["prof"]}),
        app.delete("/api/courses/au1/students/zz", headers=tok["prof"]),
        app.delete("/api/courses/au1/staff/zz", headers=tok["prof"]),
        app.put(f"/api/assignments/{aid}", json={"spec": {}, "deadline": "x"}, headers=tok["prof"]),
    ]
    assert [r.status_code for r in refused] == [404, 403, 422, 404, 404, 422]
    assert len(events(app, tok["prof"], limit=500)) == count

    # an event that cannot be written undoes its change, and a change that fails writes no event: one transaction
    db = sqlite3.connect(app.app.state.settings.data_dir / "jobs.sqlite3")
    service = app.app.state.course
    due = datetime(2027, 1, 1, tzinfo=UTC)
    try:
        db.execute("CREATE TRIGGER no_audit BEFORE INSERT ON course_audit BEGIN SELECT RAISE(ABORT, 'no room'); END")
        with pytest.raises(sqlite3.Error, match="no room"):
            service.extend(aid, "s2", due)
        db.execute("DROP TRIGGER no_audit")
        assert service.store.student(aid, "s2")["deadline"] is None  # the change was undone
        db.execute(
            "CREATE TRIGGER no_change BEFORE UPDATE ON course_enrolments BEGIN SELECT RAISE(ABORT, 'no room'); END"
        )
        with pytest.raises(sqlite3.Error, match="no room"):
            service.extend(aid, "s2", due)
        db.execute("DROP TRIGGER no_change")
        assert len(events(app, tok["prof"], limit=500)) == count  # no event of either
        service.extend(aid, "s2", due)  # and with room again, both
        assert service.store.student(aid, "s2")["deadline"] == due.timestamp()
        assert events(app, tok["prof"], limit=1)[0]["action"] == "extension"
    finally:
        db.execute("DROP TRIGGER IF EXISTS no_audit")
        db.execute("DROP TRIGGER IF EXISTS no_change")
        db.close()


def test_audit_a_page_of_the_most_events_says_there_is_another(app):
    """501 events of a course (written as a change would: By.record in a transaction): a page of 500, `next`, the
    one left; the CSV holds them all."""
    assert app.post("/api/courses", json={"id": "au3", "name": "au3"}, headers=ADMIN).status_code == 201
    service = app.app.state.course
    with Transaction(service.store.db) as db:
        for i in range(MAX_LIMIT + 1):
            By("admin", T0.timestamp() + i).record(db, "student.add", Target("au3", student=f"p{i}"), None, {"i": i})
    first = app.get("/api/courses/au3/audit", params={"limit": MAX_LIMIT}).json()
    assert len(first["events"]) == MAX_LIMIT
    assert first["next"] == first["events"][-1]["id"]
    assert first["events"][0]["after"] == {"i": MAX_LIMIT}
    rest = app.get("/api/courses/au3/audit", params={"limit": MAX_LIMIT, "before": first["next"]}).json()
    assert [e["after"] for e in rest["events"]] == [{"i": 0}]
    assert rest["next"] is None
    rows = list(csv.DictReader(io.StringIO(app.get("/api/courses/au3/audit.csv").text)))
    assert len(rows) == MAX_LIMIT + 1
    assert rows[-1]["student"] == "p0"


def test_audit_a_join_of_an_open_assignment_is_the_students_own(app, course):
    tok, _, _ = course
    r = app.post("/api/courses/au2/assignments", json=body(open=True), headers=tok["other"])
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    joined = app.post(f"/api/assignments/{aid}/join", json={"name": "Zoë"}, headers={"Authorization": ""})
    assert joined.status_code == 200, joined.text
    sid = joined.json()["id"]
    e = one(app.get("/api/courses/au2/audit", headers=tok["other"]).json()["events"], "student.join")
    assert (e["who"], e["why"], e["before"]) == (f"student:{sid}", "joined", None)
    assert e["target"] == {"course": "au2", "assignment": aid, "student": sid}
    assert e["after"] == {"name": "Zoë", "email": "", "self_declared": True}
    assert app.get("/api/courses/au2/audit", headers=bearer(joined.json()["token"])).status_code == 404
