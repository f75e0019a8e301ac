"""The course's audit trail (docs/assignments.md, "The audit trail"): every change to a grade, an extension, an
assignment (publish, edit, regrade), the roster (a student added, changed, removed, a link re-issued) and the
staff, as one row of `course_audit`: when (`at`, the app's clock), who (`who`: "instructor:<id>", "ta:<id>",
"admin", "student:<id>", "lms"), what (`action`), on what (`target`: the course, and the assignment, student,
submission or staff member it names), what it was before and after (JSON), and why (`why`, free text).

**An event is written in the same transaction as its change.** A change's store method takes a `By` (who, when,
why: `CourseBase.by(who, why)`) and calls `by.record(db, action, target, before, after)` on its transaction's
connection, where it reads `before` too: so the change and its row commit together, and a change that fails
(or a row that cannot be written) leaves neither. A store method called without a `By` records nothing.

**Adding an audited change** (a manual grade, a regrade answer, a token balance, a release): in the store
method that makes it, take `by: By | None = None` and, inside its `with self._tx() as db:`, call
`record(by, db, "manual.grade", Target(cid, aid, student=..., submission=...), before, after)` (a no-op without a
`By`); the mixin passes `self.by(who, why)`. One call; `before`/`after` are whatever JSON says the value best
(a dict of the fields that change).

Reading it: `events(db, cid, ...)` (newest first, filtered by student or assignment, paged by the id of the last
event seen: `before`), `events_csv(rows)` (formula-safe cells, tracer/tools/spreadsheet)."""

from __future__ import annotations

import io
import json
import sqlite3
from dataclasses import dataclass
from typing import Any, cast

from server.core.roles import Role
from server.course.people import Who
from server.course.policy import iso
from server.course.schema import AuditEvent
from tracer.tools import spreadsheet

MAX_LIMIT = 500  # events in one page at most (the API's `limit`)
DEFAULT_LIMIT = 100


@dataclass(frozen=True)
class Target:
    """What a change is to: always a course; an assignment, a student, a submission or a staff member in it."""

    course: str
    assignment: str | None = None
    student: str | None = None
    submission: str | None = None
    staff: str | None = None

    def json(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if v is not None}


@dataclass(frozen=True)
class By:
    """Who makes a change, when (the app's clock) and why: what a store method records its events with."""

    who: str
    at: float
    why: str = ""

    def record(self, db: sqlite3.Connection, action: str, target: Target, before: Any, after: Any) -> None:
        """One event, on `db` inside the change's transaction."""
        db.execute(
            "INSERT INTO course_audit (course_id, at, who, action, assignment_id, student, target, before, after, why)"
            " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (target.course, self.at, self.who, action, target.assignment, target.student, json.dumps(target.json()),
             None if before is None else json.dumps(before), None if after is None else json.dumps(after),
             self.why[:1000]),
        )  # fmt: skip


def record(by: By | None, db: sqlite3.Connection, action: str, target: Target, before: Any, after: Any) -> None:
    """`by.record(...)`, or nothing when the change is not audited (no `By`)."""
    if by is not None:
        by.record(db, action, target, before, after)


def who_of(who: Who) -> str:
    """The caller as the trail names them."""
    if who.student is not None:
        return f"student:{who.student['student']}"
    if who.role == Role.ADMIN or who.person is None:
        return str(Role.ADMIN)
    return f"{who.role}:{who.person}"


def events(
    db: sqlite3.Connection,
    cid: str,
    student: str | None = None,
    assignment: str | None = None,
    limit: int = DEFAULT_LIMIT,
    before: int | None = None,
) -> list[AuditEvent]:
    """The course's events, newest first: only a student's or an assignment's when named; at most `limit` (bounded:
    MAX_LIMIT and one more, which tells a page that there is another), those written before event id `before`
    (the last one of the page before)."""
    sql, args = "SELECT * FROM course_audit WHERE course_id = ?", [cid]
    if student is not None:
        sql, args = sql + " AND student = ?", [*args, student]
    if assignment is not None:
        sql, args = sql + " AND assignment_id = ?", [*args, assignment]
    if before is not None:
        sql, args = sql + " AND id < ?", [*args, before]
    rows = db.execute(sql + " ORDER BY id DESC LIMIT ?", (*args, max(1, min(limit, MAX_LIMIT + 1))))
    return [_event(r) for r in rows]


def _event(row: sqlite3.Row) -> AuditEvent:
    return {
        "id": row["id"],
        "at": cast(str, iso(row["at"])),  # NOT NULL
        "who": row["who"],
        "action": row["action"],
        "target": json.loads(row["target"]),
        "before": None if row["before"] is None else json.loads(row["before"]),
        "after": None if row["after"] is None else json.loads(row["after"]),
        "why": row["why"],
    }


CSV_COLUMNS = ["id", "at", "who", "action", "course", "assignment", "student", "target", "before", "after", "why"]


def events_csv(rows: list[AuditEvent]) -> str:
    """One row per event: the target's parts in columns of their own, before and after as JSON text; every cell
    formula-safe (spreadsheet.writer)."""
    buf = io.StringIO()
    w = spreadsheet.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for e in rows:
        t = e["target"]
        w.writerow(
            [e["id"], e["at"], e["who"], e["action"], t.get("course", ""), t.get("assignment", ""),
             t.get("student", ""), json.dumps(t), _text(e["before"]), _text(e["after"]), e["why"]]
        )  # fmt: skip
    return buf.getvalue()


def _text(value: Any) -> str:
    return "" if value is None else json.dumps(value, ensure_ascii=False)
