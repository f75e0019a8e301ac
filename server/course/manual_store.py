"""The manual grades' tables (server/course/schema.py): `course_manual_grades` (a submission's grade of one
staff-graded item: the chosen rubric levels by NAME, an override, a comment, who and when), `course_manual` (an
assignment's release and anonymity) and `course_graders` (whose submission each grader grades). A mixin of
CourseStore (server/course/store.py), on its connection; every write is one transaction, with its audit event
when given a `By` (server/course/audit.py: `manual.grade`, `assignment.release`, `manual.anonymous`,
`manual.graders`)."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import cast

from server.core.db import Tables
from server.course.audit import By, Target, record
from server.course.policy import iso
from server.course.schema import ManualGrade, ManualGradeRow, ManualRow


class ManualTables(Tables):
    """The manual grades of CourseStore (its `db`)."""

    def set_manual(
        self,
        aid: str,
        sid: str,
        item: str,
        row: ManualGrade,
        now: float,
        by: By | None = None,
        target: Target | None = None,
        points: Callable[[ManualGrade], float] | None = None,
    ) -> None:
        """A submission's grade of `item` (row: rubric [names], points (an override or None), comment, grader).
        With `by`: a `manual.grade` event on `target`, the grade before (None: the first) and after, each with its
        `points` (the mixin's score of a row by the current spec)."""
        with self._tx() as db:
            was = db.execute(
                "SELECT rubric, points, comment, grader FROM course_manual_grades WHERE submission_id = ? AND item = ?",
                (sid, item),
            ).fetchone()
            if by is not None and target is not None:
                old = None if was is None else cast(ManualGrade, {**dict(was), "rubric": json.loads(was["rubric"])})
                record(by, db, "manual.grade", target, _grade(item, old, points), _grade(item, row, points))
            db.execute(
                "INSERT INTO course_manual_grades (submission_id, item, assignment_id, rubric, points, comment,"
                " grader, graded_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (submission_id, item) DO UPDATE SET"
                " rubric = excluded.rubric, points = excluded.points, comment = excluded.comment,"
                " grader = excluded.grader, graded_at = excluded.graded_at",
                (sid, item, aid, json.dumps(row["rubric"]), row["points"], row["comment"], row["grader"], now),
            )

    def manual_grades(self, aid: str, sid: str | None = None) -> dict[str, dict[str, ManualGradeRow]]:
        """{submission id: {item: its grade}} of an assignment (or of one submission)."""
        sql, args = "SELECT * FROM course_manual_grades WHERE assignment_id = ?", (aid,)
        if sid is not None:
            sql, args = sql + " AND submission_id = ?", (aid, sid)
        out: dict[str, dict[str, ManualGradeRow]] = {}
        for r in self.db.execute(sql, args):
            row = cast(ManualGradeRow, {**dict(r), "rubric": json.loads(r["rubric"])})
            out.setdefault(row["submission_id"], {})[row["item"]] = row
        return out

    def manual_state(self, aid: str) -> ManualRow:
        """{released_at, released_by, anonymous} of an assignment (not released, not anonymous: no row yet)."""
        row = self.db.execute("SELECT * FROM course_manual WHERE assignment_id = ?", (aid,)).fetchone()
        if row is None:
            return {"assignment_id": aid, "released_at": None, "released_by": None, "anonymous": 0}
        return cast(ManualRow, dict(row))

    def release_manual(self, aid: str, who: str | None, now: float, by: By | None = None,
                       target: Target | None = None) -> None:  # fmt: skip
        with self._tx() as db:
            was = self.manual_state(aid)["released_at"]
            if by is not None and target is not None:
                record(by, db, "assignment.release", target, {"released_at": iso(was)}, {"released_at": iso(now)})
            db.execute(
                "INSERT INTO course_manual (assignment_id, released_at, released_by) VALUES (?, ?, ?)"
                " ON CONFLICT (assignment_id) DO UPDATE SET released_at = excluded.released_at,"
                " released_by = excluded.released_by",
                (aid, now, who),
            )

    def set_anonymous(self, aid: str, anonymous: bool, by: By | None = None, target: Target | None = None) -> None:
        with self._tx() as db:
            was = bool(self.manual_state(aid)["anonymous"])
            if by is not None and target is not None and was != anonymous:
                record(by, db, "manual.anonymous", target, {"anonymous": was}, {"anonymous": anonymous})
            db.execute(
                "INSERT INTO course_manual (assignment_id, anonymous) VALUES (?, ?)"
                " ON CONFLICT (assignment_id) DO UPDATE SET anonymous = excluded.anonymous",
                (aid, int(anonymous)),
            )

    def set_graders(self, aid: str, pairs: list[tuple[str, str]], by: By | None = None,
                    target: Target | None = None) -> None:  # fmt: skip
        """Each (student, grader) of an assignment, replacing its earlier assignment of graders; with `by`: a
        `manual.graders` event, {student: grader} before and after."""
        with self._tx() as db:
            if by is not None and target is not None:
                before = self.graders(aid)
                record(by, db, "manual.graders", target, {"graders": before or None}, {"graders": dict(pairs)})
            db.execute("DELETE FROM course_graders WHERE assignment_id = ?", (aid,))
            db.executemany(
                "INSERT INTO course_graders (assignment_id, student, grader) VALUES (?, ?, ?)",
                [(aid, s, g) for s, g in pairs],
            )

    def record_rescore(self, db, by: By, target: Target, old: dict, new: dict) -> None:
        """In an edit's transaction (CourseStore.add_version): a `manual.rescore` event when the edit changes the
        points of a manual item or of a rubric level that grades of the assignment use: each changed one's points
        before and after ("item" or "item: level") and how many grades move."""
        was, now = _points(old), _points(new)
        changed = sorted(k for k in was.keys() & now.keys() if was[k] != now[k])
        if not changed:
            return
        moved = 0
        for r in db.execute("SELECT item, rubric, points FROM course_manual_grades WHERE assignment_id = ?",
                            (target.assignment,)):  # fmt: skip
            levels = {f"{r['item']}: {n}" for n in json.loads(r["rubric"])}
            moved += int(r["item"] in changed or (r["points"] is None and not levels.isdisjoint(changed)))
        before, after = {"points": {k: was[k] for k in changed}}, {"points": {k: now[k] for k in changed}}
        record(by, db, "manual.rescore", target, before, {**after, "grades": moved})

    def graders(self, aid: str) -> dict[str, str]:
        """{student: grader} of an assignment ({}: not assigned)."""
        rows = self.db.execute("SELECT student, grader FROM course_graders WHERE assignment_id = ?", (aid,))
        return {r[0]: r[1] for r in rows}


def _grade(item: str, row: ManualGrade | None, points: Callable[[ManualGrade], float] | None) -> dict | None:
    """A grade as the audit trail keeps it: the item, its points, the levels chosen, the override, the comment."""
    if row is None:
        return None
    out = {"item": item, "rubric": row["rubric"], "override": row["points"], "comment": row["comment"]}
    return {**out, "points": points(row) if points is not None else row["points"], "grader": row["grader"]}


def _points(spec: dict) -> dict[str, float]:
    """{"item": points, "item: level": points} of a spec's manual items (as JSON)."""
    out = {}
    for m in spec.get("manual") or []:
        out[m["name"]] = m["points"]
        for level in m.get("rubric") or []:
            out[f"{m['name']}: {level['name']}"] = level["points"]
    return out
