"""The course's submissions table (`course_submissions`, server/course/schema.py): one per submission, written
when its body is accepted, with the attempts it holds (its grade is its grading run's row, read, never copied).
A mixin of CourseStore (server/course/store.py), on its connection."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable
from typing import cast

from server.core.db import Tables
from server.course.audit import By, Target, record
from server.course.schema import SubmissionRow, SubmissionWithGrade

# a submission that holds an attempt: not (yet) found invalid or ungradable by its grading
HOLDS_ATTEMPT = "NOT (g.stage IS 'graded' AND g.status IN ('invalid', 'failed'))"


class SubmissionTables(Tables):
    """The submissions of CourseStore (its `db`)."""

    # -- submissions ---------------------------------------------------------------------------

    def add_submission(
        self,
        sub: dict,
        max_attempts: int | None,
        per_hour: int,
        hour_ago: float,
        also: Callable[[sqlite3.Connection], object] | None = None,
        before: Callable[[sqlite3.Connection], dict] | None = None,
    ) -> str | None:
        """The submission's row, unless the student is past a cap: then which one ("attempts" or "hour"),
        with nothing written. Counting and writing are one transaction, so a burst cannot pass a cap. `also`
        writes more in the same transaction (its row in the grading run: then it is `handed` at once), so the
        two rows are kept together or neither is (a full disk). `before` reads what it needs in the same
        transaction and gives the row's last fields (the late tokens it spends: server/course/tokens.py), or
        raises to keep nothing."""
        with self._tx() as db:
            who = (sub["assignment_id"], sub["student"])
            recent = db.execute(
                "SELECT COUNT(*) FROM course_submissions WHERE assignment_id = ? AND student = ? AND accepted_at > ?",
                (*who, hour_ago),
            ).fetchone()[0]
            if recent >= per_hour:
                return "hour"
            if max_attempts is not None and self._attempts(db, *who) >= max_attempts:
                return "attempts"
            if before is not None:
                sub.update(before(db))
            db.execute(
                "INSERT INTO course_submissions (id, assignment_id, student, version, run_id, kind, file,"
                " accepted_at, late, handed, tokens_spent) VALUES (:id, :assignment_id, :student, :version, :run_id,"
                " :kind, :file, :accepted_at, :late, :handed, :tokens_spent)",
                {"tokens_spent": 0, **sub, "handed": int(also is not None)},
            )
            if also is not None:
                also(db)
        return None

    def attempts(self, aid: str, student: str) -> int:
        return self._attempts(self.db, aid, student)

    @staticmethod
    def _attempts(db: sqlite3.Connection, aid: str, student: str) -> int:
        return db.execute(
            "SELECT COUNT(*) FROM course_submissions s LEFT JOIN grading_items g ON g.run_id = s.run_id"
            f" AND g.student = s.id WHERE s.assignment_id = ? AND s.student = ? AND {HOLDS_ATTEMPT}",
            (aid, student),
        ).fetchone()[0]

    def handed(self, sid: str, run_id: str) -> None:
        """Its row is in `run_id` (unless a regrade moved it to another run meanwhile: then it is handed again)."""
        self.db.execute("UPDATE course_submissions SET handed = 1 WHERE id = ? AND run_id = ?", (sid, run_id))

    def unhanded(self) -> list[SubmissionRow]:
        """Submissions accepted but not yet in their grading run (a server stopped in between)."""
        rows = self.db.execute("SELECT * FROM course_submissions WHERE handed = 0 ORDER BY accepted_at")
        return [cast(SubmissionRow, dict(r)) for r in rows]

    def regrade(self, aid: str, version: int, run_id: str, by: By | None = None) -> list[SubmissionRow]:
        """Every submission of the assignment moved to a new version's run, to be handed to it again. With `by`:
        a `regrade` event, the versions the submissions were graded under before (and how many) and the new one."""
        with self._tx() as db:
            if by is not None:
                rows = db.execute(
                    "SELECT version, COUNT(*) AS n FROM course_submissions WHERE assignment_id = ?"
                    " GROUP BY version ORDER BY version",
                    (aid,),
                ).fetchall()
                cid = db.execute("SELECT course_id FROM course_assignments WHERE id = ?", (aid,)).fetchone()[0]
                before = {"versions": {str(r["version"]): r["n"] for r in rows}}
                after = {"version": version, "submissions": sum(r["n"] for r in rows)}
                record(by, db, "regrade", Target(cid, aid), before, after)
            db.execute(
                "UPDATE course_submissions SET version = ?, run_id = ?, handed = 0 WHERE assignment_id = ?",
                (version, run_id, aid),
            )
        return [s for s in self.unhanded() if s["assignment_id"] == aid]

    def submissions(self, aid: str, student: str | None = None) -> list[SubmissionWithGrade]:
        """Submissions (one student's, or all) in the order they came, each with its grading row's stage,
        status and exact score (None until graded)."""
        sql = (
            "SELECT s.*, g.stage, g.status, g.score, g.max_score FROM course_submissions s LEFT JOIN grading_items g"
            " ON g.run_id = s.run_id AND g.student = s.id WHERE s.assignment_id = ?"
        )
        args: tuple = (aid,)
        if student is not None:
            sql, args = sql + " AND s.student = ?", (aid, student)
        rows = self.db.execute(sql + " ORDER BY s.accepted_at, s.rowid", args)
        return [cast(SubmissionWithGrade, dict(r)) for r in rows]

    def submission_of(self, sid: str) -> tuple[str, str] | None:
        """(assignment, student) of a submission, by its id alone."""
        row = self.db.execute("SELECT assignment_id, student FROM course_submissions WHERE id = ?", (sid,)).fetchone()
        return (row[0], row[1]) if row else None

    def submission(self, aid: str, sid: str) -> SubmissionWithGrade | None:
        row = self.db.execute(
            "SELECT s.*, g.stage, g.status, g.score, g.max_score FROM course_submissions s LEFT JOIN grading_items g"
            " ON g.run_id = s.run_id AND g.student = s.id WHERE s.assignment_id = ? AND s.id = ?",
            (aid, sid),
        ).fetchone()
        return cast(SubmissionWithGrade, dict(row)) if row else None
