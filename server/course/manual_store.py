"""The manual grades' tables (server/course/schema.py): `course_manual_grades` (a submission's grade of one
staff-graded item: the chosen rubric levels by NAME, an override, a comment, who and when), `course_manual` (an
assignment's release and anonymity) and `course_graders` (whose submission each grader grades). A mixin of
CourseStore (server/course/store.py), on its connection; every write is one statement."""

from __future__ import annotations

import json

from server.core.db import Tables


class ManualTables(Tables):
    """The manual grades of CourseStore (its `db`)."""

    def set_manual(self, aid: str, sid: str, item: str, row: dict, now: float) -> None:
        """A submission's grade of `item` (row: rubric [names], points (an override or None), comment, grader)."""
        self.db.execute(
            "INSERT INTO course_manual_grades (submission_id, item, assignment_id, rubric, points, comment, grader,"
            " graded_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (submission_id, item) DO UPDATE SET"
            " rubric = excluded.rubric, points = excluded.points, comment = excluded.comment,"
            " grader = excluded.grader, graded_at = excluded.graded_at",
            (sid, item, aid, json.dumps(row["rubric"]), row["points"], row["comment"], row["grader"], now),
        )

    def manual_grades(self, aid: str, sid: str | None = None) -> dict[str, dict[str, dict]]:
        """{submission id: {item: its grade}} of an assignment (or of one submission)."""
        sql, args = "SELECT * FROM course_manual_grades WHERE assignment_id = ?", (aid,)
        if sid is not None:
            sql, args = sql + " AND submission_id = ?", (aid, sid)
        out: dict[str, dict[str, dict]] = {}
        for r in self.db.execute(sql, args):
            row = dict(r)
            row["rubric"] = json.loads(row["rubric"])
            out.setdefault(row["submission_id"], {})[row["item"]] = row
        return out

    def manual_state(self, aid: str) -> dict:
        """{released_at, released_by, anonymous} of an assignment (not released, not anonymous: no row yet)."""
        row = self.db.execute("SELECT * FROM course_manual WHERE assignment_id = ?", (aid,)).fetchone()
        return dict(row) if row else {"assignment_id": aid, "released_at": None, "released_by": None, "anonymous": 0}

    def release_manual(self, aid: str, who: str | None, now: float) -> None:
        self.db.execute(
            "INSERT INTO course_manual (assignment_id, released_at, released_by) VALUES (?, ?, ?)"
            " ON CONFLICT (assignment_id) DO UPDATE SET released_at = excluded.released_at,"
            " released_by = excluded.released_by",
            (aid, now, who),
        )

    def set_anonymous(self, aid: str, anonymous: bool) -> None:
        self.db.execute(
            "INSERT INTO course_manual (assignment_id, anonymous) VALUES (?, ?)"
            " ON CONFLICT (assignment_id) DO UPDATE SET anonymous = excluded.anonymous",
            (aid, int(anonymous)),
        )

    def set_graders(self, aid: str, pairs: list[tuple[str, str]]) -> None:
        """Each (student, grader) of an assignment, replacing its earlier assignment of graders."""
        with self._tx() as db:
            db.execute("DELETE FROM course_graders WHERE assignment_id = ?", (aid,))
            db.executemany(
                "INSERT INTO course_graders (assignment_id, student, grader) VALUES (?, ?, ?)",
                [(aid, s, g) for s, g in pairs],
            )

    def graders(self, aid: str) -> dict[str, str]:
        """{student: grader} of an assignment ({}: not assigned)."""
        rows = self.db.execute("SELECT student, grader FROM course_graders WHERE assignment_id = ?", (aid,))
        return {r[0]: r[1] for r in rows}
