"""The course's roster tables (server/course/schema.py): `course_members` (a course's roster, enrolled once:
one identity per student per course) and `course_enrolments` (who is on an assignment's roster, with their
extension if any). A mixin of CourseStore (server/course/store.py), on its connection; each change records its
audit event in its own transaction when given a `By` (server/course/audit.py)."""

from __future__ import annotations

import sqlite3
from typing import cast

from server.core.db import Tables
from server.core.roles import Kind
from server.course.audit import By, Target, record
from server.course.policy import iso
from server.course.schema import ExtensionRow, MemberRow, StudentRow

# A roster student as the service reads one (an enrolment joined with its member): the columns of the
# per-assignment roster of before courses, so that every rule reads a student as it did.
STUDENT = (
    "SELECT e.assignment_id, e.student, m.name, m.email, m.self_declared, e.deadline, e.created_at, m.course_id,"
    " m.lti_user, m.left_at FROM course_enrolments e JOIN course_assignments a ON a.id = e.assignment_id"
    " JOIN course_members m ON m.course_id = a.course_id AND m.student = e.student"
)


class RosterTables(Tables):
    """A course's members and an assignment's enrolments, of CourseStore (its `db`)."""

    # -- the course's members ------------------------------------------------------------------

    def members(self, cid: str) -> list[MemberRow]:
        rows = self.db.execute("SELECT * FROM course_members WHERE course_id = ? ORDER BY student", (cid,))
        return [cast(MemberRow, dict(r)) for r in rows]

    def member(self, cid: str, student: str) -> MemberRow | None:
        row = self.db.execute(
            "SELECT * FROM course_members WHERE course_id = ? AND student = ?", (cid, student)
        ).fetchone()
        return cast(MemberRow, dict(row)) if row else None

    def roster_kind(self, token_hash: str) -> str | None:
        """How this token's hash is known to a course: "roster" (a member an instructor or an LMS put there, or
        staff), "joined" (a member who only joined an open assignment by a name), or None (unknown)."""
        row = self.db.execute(
            "SELECT t.kind, m.self_declared FROM course_tokens t LEFT JOIN course_members m ON t.kind = 'student'"
            " AND m.course_id = t.course_id AND m.student = t.person WHERE t.token_hash = ?",
            (token_hash,),
        ).fetchone()
        if row is None or (row["kind"] == Kind.STUDENT and row["self_declared"] is None):
            return None
        return "joined" if row["kind"] == Kind.STUDENT and row["self_declared"] else "roster"

    def add_joined(self, aid: str, cid: str, row: dict, now: float, most: int, by: By | None = None) -> bool:
        """A self-declared member on assignment `aid` (an open assignment's join), unless it already has `most` of
        them: counted and added in one transaction, so that joins at once cannot pass the cap."""
        with self._tx() as db:
            have = db.execute(
                "SELECT COUNT(*) FROM course_enrolments e JOIN course_members m ON m.course_id = ?"
                " AND m.student = e.student WHERE e.assignment_id = ? AND m.self_declared = 1",
                (cid, aid),
            ).fetchone()[0]
            if have >= most:
                return False
            db.execute(
                "INSERT INTO course_members (course_id, student, name, email, self_declared, created_at)"
                " VALUES (?, ?, ?, ?, 1, ?)",
                (cid, row["student"], row["name"], row["email"], now),
            )
            db.execute(
                "INSERT INTO course_enrolments (assignment_id, student, created_at) VALUES (?, ?, ?)",
                (aid, row["student"], now),
            )
            after = {"name": row["name"], "email": row["email"], "self_declared": True}
            record(by, db, "student.join", Target(cid, aid, student=row["student"]), None, after)
        return True

    def add_members(self, cid: str, rows: list[dict], now: float, enrol: list[str], by: By | None = None) -> list[str]:
        """Members (dicts: student, name, email, self_declared, every, lti_user) in one transaction: a new one
        added, one already there gets the name and email given (and `every` once set stays set); each enrolled in
        the assignments `enrol` names (and, with `every`, in every assignment of the course). The ids added.
        With `by`: a `student.add` event for each one added, `student.change` for one whose name, email or
        `every` changed, `student.enrol` for one already a member newly on an assignment `enrol` names."""
        added = []
        with self._tx() as db:
            for r in rows:
                was = db.execute(
                    "SELECT name, email, every FROM course_members WHERE course_id = ? AND student = ?",
                    (cid, r["student"]),
                ).fetchone()
                cur = db.execute(
                    "UPDATE course_members SET name = ?, email = ?, every = MAX(every, ?),"
                    " lti_user = COALESCE(?, lti_user) WHERE course_id = ? AND student = ?",
                    (r["name"], r["email"], int(r.get("every", 0)), r.get("lti_user"), cid, r["student"]),
                )
                if not cur.rowcount:
                    db.execute(
                        "INSERT INTO course_members (course_id, student, name, email, self_declared, every, lti_user,"
                        " created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        (cid, r["student"], r["name"], r["email"], int(r.get("self_declared", 0)),
                         int(r.get("every", 0)), r.get("lti_user"), now),
                    )  # fmt: skip
                    added.append(r["student"])
                if by is not None:
                    _member_event(db, by, cid, r, was, enrol)
                aids = list(enrol)
                if r.get("every"):
                    aids += [a[0] for a in db.execute("SELECT id FROM course_assignments WHERE course_id = ?", (cid,))]
                for aid in dict.fromkeys(aids):
                    enrolled = db.execute(
                        "INSERT OR IGNORE INTO course_enrolments (assignment_id, student, created_at) VALUES (?, ?, ?)",
                        (aid, r["student"], now),
                    ).rowcount
                    if enrolled and was is not None and aid in enrol:
                        target = Target(cid, aid, student=r["student"])
                        record(by, db, "student.enrol", target, None, {"enrolled": True})
        return added

    def set_left(self, cid: str, students: list[str], when: float | None, by: By | None = None) -> int:
        """Members who left the course's LMS course (`when`: inactive from then; kept with their submissions and
        grades) or came back (None: active again). How many changed (with `by`: a `student.left` or
        `student.back` event for each)."""
        changed = 0
        with self._tx() as db:
            for s in students:
                n = db.execute(
                    "UPDATE course_members SET left_at = ? WHERE course_id = ? AND student = ? AND"
                    + (" left_at IS NULL" if when is not None else " left_at IS NOT NULL"),
                    (when, cid, s),
                ).rowcount
                changed += n
                if n:
                    action, before, after = (
                        ("student.left", True, False) if when is not None else ("student.back", False, True)
                    )
                    record(by, db, action, Target(cid, student=s), {"active": before}, {"active": after})
        return changed

    def remove_member(self, cid: str, student: str, by: By | None = None) -> bool:
        """Off the course's rosters (their submissions are kept; their tokens stop working)."""
        with self._tx() as db:
            was = db.execute(
                "SELECT name, email, every FROM course_members WHERE course_id = ? AND student = ?", (cid, student)
            ).fetchone()
            cur = db.execute("DELETE FROM course_members WHERE course_id = ? AND student = ?", (cid, student))
            if was is not None:
                before = {"name": was["name"], "email": was["email"], "every": bool(was["every"])}
                record(by, db, "student.remove", Target(cid, student=student), before, None)
            db.execute(
                "DELETE FROM course_enrolments WHERE student = ? AND assignment_id IN"
                " (SELECT id FROM course_assignments WHERE course_id = ?)",
                (student, cid),
            )
            db.execute(
                "DELETE FROM course_tokens WHERE course_id = ? AND kind = 'student' AND person = ?", (cid, student)
            )
        return cur.rowcount == 1

    # -- an assignment's roster (its enrolments) -----------------------------------------------

    def students(self, aid: str) -> list[StudentRow]:
        rows = self.db.execute(STUDENT + " WHERE e.assignment_id = ? ORDER BY e.student", (aid,))
        return [cast(StudentRow, dict(r)) for r in rows]

    def student(self, aid: str, student: str) -> StudentRow | None:
        row = self.db.execute(STUDENT + " WHERE e.assignment_id = ? AND e.student = ?", (aid, student)).fetchone()
        return cast(StudentRow, dict(row)) if row else None

    def by_token(self, aid: str, token_hash: str) -> StudentRow | None:
        """The student of this assignment's roster whose token this is (a member of its course enrolled in it)."""
        row = self.db.execute(
            STUDENT + " JOIN course_tokens t ON t.course_id = m.course_id AND t.kind = 'student'"
            " AND t.person = m.student WHERE e.assignment_id = ? AND t.token_hash = ?",
            (aid, token_hash),
        ).fetchone()
        return cast(StudentRow, dict(row)) if row else None

    def enrol(self, aid: str, student: str, now: float, by: By | None = None) -> None:
        """A member of the assignment's course on its roster (if not already: then a `student.enrol` event)."""
        with self._tx() as db:
            added = db.execute(
                "INSERT OR IGNORE INTO course_enrolments (assignment_id, student, created_at) VALUES (?, ?, ?)",
                (aid, student, now),
            ).rowcount
            if added and by is not None:
                cid = db.execute("SELECT course_id FROM course_assignments WHERE id = ?", (aid,)).fetchone()[0]
                record(by, db, "student.enrol", Target(cid, aid, student=student), None, {"enrolled": True})

    def extend(
        self,
        aid: str,
        student: str,
        deadline: float | None,
        who: str = "",
        why: str = "",
        now: float = 0,
        by: By | None = None,
    ) -> bool:
        """Their own deadline (None: the assignment's), and the grant kept in its history (before, after, who,
        why, when); with `by`, an `extension` audit event: the deadline before and after (ISO 8601; null: the
        assignment's). One transaction."""
        with self._tx() as db:
            row = db.execute(
                "SELECT e.deadline, a.course_id FROM course_enrolments e JOIN course_assignments a"
                " ON a.id = e.assignment_id WHERE e.assignment_id = ? AND e.student = ?",
                (aid, student),
            ).fetchone()
            if row is None:
                return False
            db.execute(
                "UPDATE course_enrolments SET deadline = ? WHERE assignment_id = ? AND student = ?",
                (deadline, aid, student),
            )
            db.execute(
                "INSERT INTO course_extensions (assignment_id, student, before, after, who, why, at)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                (aid, student, row[0], deadline, who, why, now),
            )
            target = Target(row["course_id"], aid, student=student)
            record(by, db, "extension", target, {"deadline": iso(row[0])}, {"deadline": iso(deadline)})
        return True

    def extensions(self, aid: str, student: str) -> list[ExtensionRow]:
        """A student's extensions of an assignment, oldest first."""
        rows = self.db.execute(
            "SELECT * FROM course_extensions WHERE assignment_id = ? AND student = ? ORDER BY at, rowid", (aid, student)
        )
        return [cast(ExtensionRow, dict(r)) for r in rows]


def _member_event(db: sqlite3.Connection, by: By, cid: str, r: dict, was: sqlite3.Row | None, enrol: list) -> None:
    """A roster row's event: the member added, or changed (their name, email, or on every assignment now)."""
    after = {"name": r["name"], "email": r["email"], "every": bool(r.get("every", 0)) or bool(was and was["every"])}
    aid = enrol[0] if len(enrol) == 1 and was is None else None
    if was is None:
        record(by, db, "student.add", Target(cid, aid, student=r["student"]), None, after)
        return
    before = {"name": was["name"], "email": was["email"], "every": bool(was["every"])}
    if before != after:
        record(by, db, "student.change", Target(cid, student=r["student"]), before, after)
