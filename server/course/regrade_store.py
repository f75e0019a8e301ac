"""Regrade requests' tables (server/course/schema.py): `course_regrade_requests` (one request: the submission, the
item, the reason, its status and latest answer), `course_regrade_events` (each change of a request: asked, each
answer, kept in order) and `course_test_overrides` (a test's points set by an accepted request: the auto part's
override, with the points the grading gave). Functions on CourseStore (its `db`, `_tx`); each change is one
transaction with its events and its audit record (server/course/audit.py)."""

from __future__ import annotations

import json
import sqlite3
import uuid
from typing import cast

from server.course.audit import By, Target, record
from server.course.schema import OverrideRow, RegradeEvent, RegradeRequestRow

OPEN, ACCEPTED, DECLINED = "open", "accepted", "declined"


def _request(row: sqlite3.Row) -> RegradeRequestRow:
    return cast(RegradeRequestRow, dict(row))


def create(store, req: dict, target: Target, by: By) -> RegradeRequestRow | None:
    """A new open request (req: assignment_id, submission_id, student, item, kind, reason, points), its first event
    and its `regrade.request` audit event, together; None when an open one for that item of that submission exists
    (checked in the same transaction: two at once make one)."""
    rid = uuid.uuid4().hex
    with store._tx() as db:
        if db.execute(
            "SELECT 1 FROM course_regrade_requests WHERE submission_id = ? AND item = ? AND status = ?",
            (req["submission_id"], req["item"], OPEN),
        ).fetchone():  # fmt: skip
            return None
        db.execute(
            "INSERT INTO course_regrade_requests (id, assignment_id, submission_id, student, item, kind, reason,"
            " status, reply, points, created_at, answered_at, answered_by) VALUES (?, ?, ?, ?, ?, ?, ?, ?, '', NULL,"
            " ?, NULL, NULL)",
            (rid, req["assignment_id"], req["submission_id"], req["student"], req["item"], req["kind"],
             req["reason"], OPEN, by.at),
        )  # fmt: skip
        after = {"request": rid, "item": req["item"], "status": OPEN, "reason": req["reason"], "points": req["points"]}
        _event(db, rid, by, "request", {"status": OPEN, "reason": req["reason"], "points": req["points"]})
        record(by, db, "regrade.request", target, None, after)
    return one(store, rid)


def answer(store, rid: str, status: str, reply: str, points: dict | None, target: Target, by: By) -> None:
    """A request answered (again): its status and reply, an event, the `regrade.answer` audit event; `points`
    ({before, after, test?: {version, original}}) when an accepted answer moves a test's points (written here, in
    the same transaction) or a manual item's (written by the caller through the manual grades)."""
    with store._tx() as db:
        was = db.execute("SELECT * FROM course_regrade_requests WHERE id = ?", (rid,)).fetchone()
        before = {"status": was["status"], "reply": was["reply"], "points": was["points"]}
        new_points = points["after"] if points is not None else was["points"]
        db.execute(
            "UPDATE course_regrade_requests SET status = ?, reply = ?, points = ?, answered_at = ?, answered_by = ?"
            " WHERE id = ?",
            (status, reply, new_points, by.at, by.who, rid),
        )
        if points is not None and points.get("test") is not None:
            t = points["test"]
            db.execute(
                "INSERT INTO course_test_overrides (submission_id, test, assignment_id, version, original, points,"
                " request_id, at) VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (submission_id, test) DO UPDATE SET"
                " version = excluded.version, original = excluded.original, points = excluded.points,"
                " request_id = excluded.request_id, at = excluded.at",
                (was["submission_id"], was["item"], was["assignment_id"], t["version"], t["original"], points["after"],
                 rid, by.at),
            )  # fmt: skip
        change = {"status": status, "reply": reply}
        if points is not None:
            change |= {"points_before": points["before"], "points": points["after"]}
        _event(db, rid, by, "answer", change)
        after = {"request": rid, "item": was["item"], "status": status, "reply": reply, "points": new_points}
        if points is not None:
            before["item_points"], after["item_points"] = points["before"], points["after"]
        record(by, db, "regrade.answer", target, {"request": rid, **before}, after)


def _event(db: sqlite3.Connection, rid: str, by: By, kind: str, change: dict) -> None:
    db.execute(
        "INSERT INTO course_regrade_events (request_id, at, who, kind, change) VALUES (?, ?, ?, ?, ?)",
        (rid, by.at, by.who, kind, json.dumps(change)),
    )


def one(store, rid: str) -> RegradeRequestRow | None:
    row = store.db.execute("SELECT * FROM course_regrade_requests WHERE id = ?", (rid,)).fetchone()
    return _request(row) if row else None


def of_assignment(store, aid: str, student: str | None = None, status: str | None = None) -> list[RegradeRequestRow]:
    """An assignment's requests (a student's only, one status only), open first, then oldest first."""
    sql, args = "SELECT * FROM course_regrade_requests WHERE assignment_id = ?", [aid]
    if student is not None:
        sql, args = sql + " AND student = ?", [*args, student]
    if status is not None:
        sql, args = sql + " AND status = ?", [*args, status]
    sql += " ORDER BY status != 'open', created_at, rowid"
    return [_request(r) for r in store.db.execute(sql, args)]


def events(store, rids: list[str]) -> dict[str, list[RegradeEvent]]:
    """{request id: its events, oldest first}."""
    out: dict[str, list[RegradeEvent]] = {rid: [] for rid in rids}
    if not rids:
        return out
    marks = ", ".join("?" * len(rids))
    rows = store.db.execute(
        f"SELECT * FROM course_regrade_events WHERE request_id IN ({marks}) ORDER BY id", rids
    ).fetchall()
    for r in rows:
        event = {"at": r["at"], "who": r["who"], "kind": r["kind"], **json.loads(r["change"])}
        out[r["request_id"]].append(cast(RegradeEvent, event))
    return out


def overrides(store, aid: str, sid: str | None = None) -> dict[str, dict[str, OverrideRow]]:
    """{submission id: {test: {version, original, points}}} of an assignment (or one submission)."""
    sql, args = "SELECT * FROM course_test_overrides WHERE assignment_id = ?", (aid,)
    if sid is not None:
        sql, args = sql + " AND submission_id = ?", (aid, sid)
    out: dict[str, dict[str, OverrideRow]] = {}
    for r in store.db.execute(sql, args):
        out.setdefault(r["submission_id"], {})[r["test"]] = {
            "version": r["version"], "original": r["original"], "points": r["points"]
        }  # fmt: skip
    return out
