"""Late tokens and extensions' history (server/course/tokens.py; issue #41, item 4) on a real app, its clock set by
the test (never slept to), no render needed (workers=0: a submission's tokens are known when it is accepted).

A course gives each student 3 tokens. Assignment A: deadline D, late until D + 4 days, half the points off when
late; assignment B: deadline D, no late submissions. A submission spends ceil(days late) less what was spent on the
assignment already, when the student has that many (else none: the penalty, or the refusal, as before)."""

from __future__ import annotations

import json
import threading
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import INSTRUCTOR, bearer, course_client
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
D = T0 + timedelta(days=2)
ADMIN = bearer(INSTRUCTOR)
CID = "late101"


def spec() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def scene() -> dict:
    return json.loads((EXAMPLE / "reference.json").read_text())


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("tokens-data"), T0, workers=0) as c:
        yield c


@pytest.fixture(scope="module")
def course(app):
    """The course (3 tokens each), its TA, assignments A, B and C (C: as A), and five students' tokens."""
    r = app.post("/api/courses", json={"id": CID, "name": "Late days", "late_tokens": 3}, headers=ADMIN)
    assert r.status_code == 201, r.text
    assert r.json()["late_tokens"] == 3
    r = app.post(f"/api/courses/{CID}/staff", json={"id": "ta-1", "role": "ta"}, headers=ADMIN)
    assert r.status_code == 201, r.text
    ta = bearer(r.json()["token"])
    late = {"late_until": (D + timedelta(days=4)).isoformat(), "late_penalty": 0.5}
    aids = {}
    for name, policy in (("A", late), ("B", {}), ("C", late)):
        body = {"spec": spec(), "deadline": D.isoformat(), **policy}
        r = app.post(f"/api/courses/{CID}/assignments", json=body, headers=ADMIN)
        assert r.status_code == 201, r.text
        aids[name] = r.json()["id"]
    roster = "id,name,email\nann,Ann,\nbea,Bea,\ncid,Cid,\ndan,Dan,\neve,Eve,\n"
    r = app.post(f"/api/courses/{CID}/roster", content=roster, headers={"Content-Type": "text/csv", **ADMIN})
    assert r.status_code == 200, r.text
    tokens = {s["id"]: bearer(s["token"]) for s in r.json()["students"]}
    return {"ta": ta, "aids": aids, "students": tokens}


def at(app, when: datetime) -> None:
    app.app.state.clock.now = when


def hand(app, course, assignment: str, student: str, status: int = 202) -> dict:
    aid = course["aids"][assignment]
    r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": scene()}, headers=course["students"][student])
    assert r.status_code == status, r.text
    return r.json()


def brief(app, course, assignment: str, student: str) -> dict:
    r = app.get(f"/api/assignments/{course['aids'][assignment]}", headers=course["students"][student])
    assert r.status_code == 200, r.text
    return r.json()


def numbers(b: dict) -> tuple:
    return b["tokens_left"], b["tokens_needed_now"], b["tokens_missing_now"]


def test_late_tokens_setting_is_validated_and_named(app, course):
    for bad in (-1, 61, "three", 2.5, True):
        r = app.patch(f"/api/courses/{CID}", json={"late_tokens": bad}, headers=ADMIN)
        assert r.status_code == 422, (bad, r.text)
        assert any("late_tokens" in str(e["path"]) for e in r.json()["errors"]), r.text
        r = app.post("/api/courses", json={"id": "bad-tokens", "late_tokens": bad}, headers=ADMIN)
        assert r.status_code == 422, (bad, r.text)
    assert app.get("/api/courses/bad-tokens", headers=ADMIN).status_code == 404  # nothing made
    r = app.patch(f"/api/courses/{CID}", json={"late_tokens": 3}, headers=course["ta"])
    assert r.status_code == 403, r.text  # a TA grants tokens but does not set the course's
    r = app.patch(f"/api/courses/{CID}", json={"late_tokens": 3}, headers=ADMIN)
    assert r.status_code == 200 and r.json()["late_tokens"] == 3, r.text


def test_spending_0_1_and_2_tokens_and_the_briefs_numbers(app, course):
    at(app, D - timedelta(hours=1))
    assert numbers(brief(app, course, "A", "ann")) == (3, 0, 0)
    on_time = hand(app, course, "A", "ann")
    assert (on_time["tokens_spent"], on_time["late"], on_time["penalty"]) == (0, False, 0.0)

    at(app, D + timedelta(hours=3))  # 3 hours late: one day's token
    assert numbers(brief(app, course, "A", "ann")) == (3, 1, 0)
    one = hand(app, course, "A", "ann")
    assert (one["tokens_spent"], one["late"], one["penalty"]) == (1, False, 0.0)
    b = brief(app, course, "A", "ann")
    assert numbers(b) == (2, 0, 0) and b["tokens_spent_here"] == 1
    assert b["tokens_deadline"] == "2026-12-04T12:00:00Z"  # her deadline, moved a day by the token

    at(app, D + timedelta(hours=20))  # within the day already bought: nothing more
    again = hand(app, course, "A", "ann")
    assert (again["tokens_spent"], again["late"]) == (0, False)
    at(app, D + timedelta(hours=30))  # the second day: one more
    assert numbers(brief(app, course, "A", "ann")) == (2, 1, 0)
    assert hand(app, course, "A", "ann")["tokens_spent"] == 1
    assert brief(app, course, "B", "ann")["tokens_left"] == 1  # the course's: shared by its assignments

    at(app, D + timedelta(hours=5))  # B takes nothing late: a token covers bea's day there (her deadline moves)
    assert numbers(brief(app, course, "B", "bea")) == (3, 1, 0)
    assert hand(app, course, "B", "bea")["tokens_spent"] == 1
    at(app, D + timedelta(hours=26))  # on A, a day and two hours late at once: two tokens, her last
    assert numbers(brief(app, course, "A", "bea")) == (2, 2, 0)
    two = hand(app, course, "A", "bea")
    assert (two["tokens_spent"], two["late"], two["score"]) == (2, False, None)
    at(app, D + timedelta(hours=50))
    assert numbers(brief(app, course, "B", "bea")) == (0, 0, 2)
    refused = hand(app, course, "B", "bea", status=403)
    assert refused["errors"][0]["path"] == "deadline"
    assert "needs 2 late token(s) and you have 0" in refused["errors"][0]["message"], refused

    # the staff's views agree: the submission's tokens, its late mark as read now
    aid = course["aids"]["A"]
    r = app.get(f"/api/assignments/{aid}/submissions/{one['id']}", headers=ADMIN)
    assert (r.json()["tokens_spent"], r.json()["late"]) == (1, False)
    r = app.get(f"/api/courses/{CID}/students/ann/tokens", headers=course["ta"])
    assert r.status_code == 200, r.text
    assert {k: r.json()[k] for k in ("left", "late_tokens", "granted", "spent")} == {
        "left": 1, "late_tokens": 3, "granted": 0, "spent": 2}  # fmt: skip


def test_too_few_tokens_spend_none_and_the_penalty_applies_then_a_grant_covers_it(app, course):
    at(app, D + timedelta(days=3, hours=12))  # 4 days' tokens needed, 3 held: none spent, late
    assert numbers(brief(app, course, "A", "cid")) == (3, 0, 4)
    late = hand(app, course, "A", "cid")
    assert (late["tokens_spent"], late["late"], late["penalty"]) == (0, True, 0.5)
    assert brief(app, course, "A", "cid")["tokens_left"] == 3

    url = f"/api/courses/{CID}/students/cid/tokens"
    assert app.post(url, json={"add": 1, "why": "x"}, headers=course["students"]["cid"]).status_code == 404
    for bad in (0, -2, 61, "one"):
        r = app.post(url, json={"add": bad, "why": "ill"}, headers=course["ta"])
        assert r.status_code == 422 and "add" in str(r.json()["errors"][0]["path"]), r.text
    r = app.post(f"/api/courses/{CID}/students/nobody/tokens", json={"add": 1}, headers=course["ta"])
    assert r.status_code == 404 and r.json()["errors"][0]["path"] == "student", r.text

    at(app, D + timedelta(days=3, hours=13))
    r = app.post(url, json={"add": 1, "why": "ill on Tuesday"}, headers=course["ta"])
    assert r.status_code == 200, r.text
    t = r.json()
    assert (t["left"], t["granted"]) == (4, 1)
    assert t["grants"] == [{"at": "2026-12-07T01:00:00Z", "who": "ta-1", "add": 1, "before": 3, "after": 4,
                            "why": "ill on Tuesday"}]  # fmt: skip
    assert numbers(brief(app, course, "A", "cid")) == (4, 4, 0)
    covered = hand(app, course, "A", "cid")
    assert (covered["tokens_spent"], covered["late"], covered["penalty"]) == (4, False, 0.0)
    r = app.get(f"/api/assignments/{course['aids']['A']}/submissions/{late['id']}", headers=ADMIN)
    assert r.json()["late"] is True  # the earlier one came before the tokens: still late
    assert brief(app, course, "A", "cid")["tokens_left"] == 0
    # the grant and the spending in the course's audit trail (server/course/audit.py), each with its balance
    events = app.get(f"/api/courses/{CID}/audit", params={"student": "cid"}, headers=ADMIN).json()["events"]
    moves = [(e["action"], e["who"], e["before"], e["after"], e["why"]) for e in events if "tokens" in e["action"]]
    assert moves == [
        ("tokens.spend", "student:cid", {"tokens_left": 4}, {"tokens_left": 0, "spent": 4}, "a late submission"),
        ("tokens.grant", "ta:ta-1", {"tokens_left": 3}, {"tokens_left": 4}, "ill on Tuesday"),
    ]
    assert events[0]["target"] == {"course": CID, "assignment": course["aids"]["A"], "student": "cid"}
    made = app.get(f"/api/courses/{CID}/audit", headers=ADMIN).json()["events"]
    assert [(e["before"], e["after"]) for e in made if e["action"] == "tokens.course"] == [
        ({"late_tokens": 0}, {"late_tokens": 3})
    ]


def test_extensions_keep_their_history_and_tokens_count_from_the_students_own_deadline(app, course):
    aid = course["aids"]["A"]
    at(app, D - timedelta(days=1))
    first = D + timedelta(days=1)
    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "dan", "deadline": first.isoformat(),
                 "why": "a conference"}, headers=course["ta"])  # fmt: skip
    assert r.status_code == 200, r.text
    at(app, D - timedelta(hours=12))
    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "dan", "deadline": None}, headers=ADMIN)
    assert r.status_code == 200, r.text
    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "dan", "deadline": first.isoformat(),
                 "why": "again"}, headers=ADMIN)  # fmt: skip
    assert r.status_code == 200, r.text
    history = app.get(f"/api/assignments/{aid}/students/dan", headers=course["ta"]).json()["extensions"]
    z = "%Y-%m-%dT%H:%M:%SZ"
    assert history == [
        {"at": (D - timedelta(days=1)).strftime(z), "who": "ta-1", "before": None, "after": first.strftime(z),
         "why": "a conference"},
        {"at": (D - timedelta(hours=12)).strftime(z), "who": "admin", "before": first.strftime(z), "after": None,
         "why": ""},
        {"at": (D - timedelta(hours=12)).strftime(z), "who": "admin", "before": None, "after": first.strftime(z),
         "why": "again"},
    ]  # fmt: skip
    at(app, first + timedelta(hours=2))  # 2 hours past his own deadline: a day's token
    assert numbers(brief(app, course, "A", "dan")) == (3, 1, 0)
    assert hand(app, course, "A", "dan")["tokens_spent"] == 1
    d = app.get(f"/api/assignments/{aid}/students/dan", headers=course["ta"]).json()
    assert d["extensions"] == history
    assert d["tokens"]["left"] == 2
    assert [h["tokens_spent"] for h in d["history"]] == [1]


def test_two_submissions_at_once_never_spend_one_token_twice(app, course):
    """eve has 3 tokens and two submissions (A and C) at once, each 2 days' tokens late: one spends 2, the other
    finds 1 left, spends none and is late (the penalty); never 4 spent, never fewer than none left."""
    at(app, D + timedelta(hours=26))
    results: list[dict] = []
    barrier = threading.Barrier(2)

    def go(assignment: str) -> None:
        barrier.wait(timeout=10)
        results.append(hand(app, course, assignment, "eve"))

    threads = [threading.Thread(target=go, args=(x,)) for x in ("A", "C")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert len(results) == 2, results
    assert sorted(r["tokens_spent"] for r in results) == [0, 2], results
    assert sorted(r["late"] for r in results) == [False, True], results
    assert brief(app, course, "A", "eve")["tokens_left"] == 1
