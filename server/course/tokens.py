"""Late tokens (issue #41, item 4; docs/assignments.md, "Late tokens"): a course gives each student `late_tokens`
days to spend on late work, shared by every assignment of the course; staff grant more, each grant kept.

**The rule.** A submission that comes after the student's own deadline (an extension counted) needs as many
tokens as whole days it is late: ceil(lateness / 24 h). Tokens already spent on the same assignment count (two
tokens spent on Monday's late submission cover a second one within those two days; a third day costs one more).
When the student has enough tokens for what is missing, the submission spends exactly that and is on time: no
late mark, no penalty, and the tokens move that student's deadline and late cut-off for the assignment by as
many days (a submission past the cut-off is taken when tokens cover it). When they have too few, it spends none
(a token never half-covers a day) and the assignment's rule applies as before: late with its penalty until the
late cut-off, refused after it. Tokens once spent stay spent (an extension granted later gives none back: staff
grant them again).

A submission's late mark is read as: late when it came after the student's deadline plus the days spent on the
assignment up to it (itself included). Spending is decided in the submission's own transaction (BEGIN
IMMEDIATE: the balance read and the row written together), so two submissions at once never spend one token
twice.

Every change goes through one method (for the audit trail): `set_late_tokens` (a course's number),
`grant_tokens` (a grant), `extend` (server/course/roster.py; its history in `course_extensions`), and the spend
inside `spend_plan`.
"""

from __future__ import annotations

import logging
import math
import sqlite3

from server.core.errors import Forbidden, Invalid, NotFound
from server.course.audit import Target, record
from server.course.base import DAY, CourseBase, Decide, iso
from server.course.people import Who
from server.course.schema import AssignmentRow, CourseRow, MemberRow, StudentRow

log = logging.getLogger(__name__)

MAX_TOKENS = 60  # the most a course gives each student, and the most one grant adds


def check_tokens(n: object, path: str = "late_tokens", least: int = 0) -> int:
    """A number of tokens: an int from `least` to MAX_TOKENS; 422 naming `path` otherwise."""
    if isinstance(n, bool) or not isinstance(n, int) or not least <= n <= MAX_TOKENS:
        message = f"expected a whole number of days from {least} to {MAX_TOKENS}; got {str(n)[:40]!r}"
        raise Invalid([{"path": path, "message": message}])
    return n


def days_late(accepted: float, due: float) -> int:
    """Whole days (rounded up) `accepted` is after `due`; 0 when not after it."""
    return max(0, math.ceil((accepted - due) / DAY - 1e-9)) if accepted > due else 0


def balance(db: sqlite3.Connection, cid: str, student: str) -> int:
    """The student's tokens left in the course: the course's, plus grants, minus every submission's spent."""
    given = db.execute("SELECT late_tokens FROM courses WHERE id = ?", (cid,)).fetchone()
    granted = db.execute(
        "SELECT COALESCE(SUM(added), 0) FROM course_token_grants WHERE course_id = ? AND student = ?", (cid, student)
    ).fetchone()[0]
    spent = db.execute(
        "SELECT COALESCE(SUM(s.tokens_spent), 0) FROM course_submissions s JOIN course_assignments a"
        " ON a.id = s.assignment_id WHERE a.course_id = ? AND s.student = ?",
        (cid, student),
    ).fetchone()[0]
    return (given[0] if given else 0) + granted - spent


def spent_on(db: sqlite3.Connection, aid: str, student: str) -> int:
    """Tokens the student spent on one assignment."""
    return db.execute(
        "SELECT COALESCE(SUM(tokens_spent), 0) FROM course_submissions WHERE assignment_id = ? AND student = ?",
        (aid, student),
    ).fetchone()[0]


def plan(accepted: float, due: float, cut: float, spent: int, left: int) -> tuple[int, bool] | None:
    """(tokens to spend, late) of a submission at `accepted`, or None when it is refused (past the cut-off and
    not covered): `spent` already spent on the assignment, `left` in the course."""
    missing = days_late(accepted, due) - spent
    if missing <= 0:
        return 0, False
    if missing <= left:
        return missing, False
    return (0, True) if accepted <= cut + spent * DAY else None


class Tokens(CourseBase):
    """A course's late tokens, spent and granted (mixed into server/course/service.Course)."""

    def set_late_tokens(self, cid: str, n: int, who: Who) -> CourseRow:
        """The course's tokens per student (an int, 0 to MAX_TOKENS): every student's balance moves by the change."""
        before = self.course(cid)["late_tokens"]
        self.store.set_late_tokens(cid, check_tokens(n), self.by(who))
        log.info("course %s: late tokens %d -> %d (by %s)", cid, before, n, who.person or who.role)
        return self.course(cid)

    def tokens_left(self, cid: str, student: str) -> int:
        return balance(self.store.db, cid, student)

    def tokens_brief(self, a: AssignmentRow, student: StudentRow | MemberRow, now: float) -> dict:
        """The brief's part: the course's tokens, what is left, what a submission now would spend, and whether
        they would cover it (the assignment's deadline then moves for them)."""
        due, cut = self.deadlines(a, student)
        db = self.store.db
        left, spent = balance(db, a["course_id"], student["student"]), spent_on(db, a["id"], student["student"])
        missing = max(0, days_late(now, due) - spent)
        p = plan(now, due, cut, spent, left)
        return {
            "late_tokens": self.course(a["course_id"])["late_tokens"],
            "tokens_left": left,
            "tokens_spent_here": spent,
            "tokens_needed_now": p[0] if p is not None else 0,
            "tokens_missing_now": missing if missing > left else 0,
            "tokens_deadline": iso(due + spent * DAY),
            "tokens_cover_now": now > due and p is not None and not p[1],  # late, but on time by tokens
            "closed": p is None,  # past the cut-off and tokens cannot cover it (else a submission is taken)
        }

    def spend_plan(
        self, a: AssignmentRow, student: StudentRow | MemberRow, due: float, cut: float, accepted: float
    ) -> Decide:
        """What `CourseStore.add_submission` calls in its transaction: the tokens this submission spends and its
        late mark, read and written together; a refusal (past the cut-off, too few tokens) raises there."""

        def decide(db: sqlite3.Connection, dry: bool = False) -> dict:
            """The decision; `dry`: only the refusal, nothing recorded (the check before the file is written)."""
            sid = student["student"]
            spent, left = spent_on(db, a["id"], sid), balance(db, a["course_id"], sid)
            p = plan(accepted, due, cut, spent, left)
            if p is None:
                raise refused(due, cut, accepted, days_late(accepted, due) - spent, left)
            if p[0] and not dry:  # the student's balance moves: audited as theirs, in the submission's transaction
                after = {"tokens_left": left - p[0], "spent": p[0]}
                record(self.by(f"student:{sid}", "a late submission"), db, "tokens.spend",
                       Target(a["course_id"], a["id"], student=sid), {"tokens_left": left}, after)  # fmt: skip
                log.info("student %s spent %d late token(s) on %s (%d left)", sid, p[0], a["id"], left - p[0])
            return {"tokens_spent": p[0], "late": int(p[1])}

        return decide

    def grant_tokens(self, cid: str, student: str, add: int, why: str, who: Who) -> dict:
        """More tokens for one student of the course, kept with who, when, before, after and why."""
        check_tokens(add, "add", least=1)
        self.course(cid)
        with self.store._tx() as db:
            if db.execute(
                "SELECT 1 FROM course_members WHERE course_id = ? AND student = ?", (cid, student)
            ).fetchone() is None:  # fmt: skip
                raise NotFound([{"path": "student", "message": f"no student '{student[:80]}' in course '{cid}'"}])
            before = balance(db, cid, student)
            db.execute(
                "INSERT INTO course_token_grants (course_id, student, added, before, after, who, why, at)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (cid, student, add, before, before + add, who.person or str(who.role), why, self.now()),
            )
            target = Target(cid, student=student)
            record(
                self.by(who, why), db, "tokens.grant", target, {"tokens_left": before}, {"tokens_left": before + add}
            )
        log.info("course %s: %d late token(s) granted to %s by %s", cid, add, student, who.person or who.role)
        return self.tokens_of(cid, student)

    def tokens_of(self, cid: str, student: str) -> dict:
        """A student's tokens: left, the course's, granted, spent, and each grant (oldest first)."""
        db = self.store.db
        rows = self.store.token_grants(cid, student)
        grants = [
            {"at": iso(r["at"]), "who": r["who"], "add": r["added"], "before": r["before"], "after": r["after"],
             "why": r["why"]}
            for r in rows
        ]  # fmt: skip
        left = balance(db, cid, student)
        granted = sum(g["add"] for g in grants)
        course = self.course(cid)["late_tokens"]
        return {"student": student, "left": left, "late_tokens": course, "granted": granted,
                "spent": course + granted - left, "grants": grants}  # fmt: skip

    def extension_history(self, aid: str, student: str) -> list[dict]:
        return [
            {"at": iso(e["at"]), "who": e["who"], "before": iso(e["before"]) if e["before"] is not None else None,
             "after": iso(e["after"]) if e["after"] is not None else None, "why": e["why"]}
            for e in self.store.extensions(aid, student)
        ]  # fmt: skip


def refused(due: float, cut: float, accepted: float, missing: int, left: int) -> Forbidden:
    late = f"; late submissions were taken until {iso(cut)}" if cut > due else ""
    tokens = f"; it needs {missing} late token(s) and you have {left}" if missing > 0 else ""
    message = f"the deadline was {iso(due)}{late}; this submission came at {iso(accepted)}{tokens}"
    return Forbidden([{"path": "deadline", "message": message}])
