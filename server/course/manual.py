"""Staff-graded items (issue #41, item 2; docs/assignments.md "Staff-graded items"): a spec's `manual` items
(tracer/grading/spec.py), graded by the course's staff (instructors and TAs) from the grading queue, released by
an instructor.

- **A grade of an item** keeps the chosen rubric levels by NAME, an optional override of the points, a comment,
  the grader and the time (server/course/manual_store.py). Its points are computed from the assignment's CURRENT
  spec whenever they are read: the chosen levels' sum clamped to 0..the item's points, or the override (within the
  same range). An edit that changes a level's points changes every grade that chose it; a level or an item an edit
  removed counts nothing (its row is kept: an edit that brings it back brings the grade back).
- **The queue**: each roster student's counting submission (the one that is the grade, `Grades.counting`) that
  lacks a grade of some item, in the roster's order; when graders were assigned (`assign_graders`, round-robin
  over the roster, so each gets as many as the others within one), a grader's own only, unless they ask for
  another's (`grader`).
- **Anonymous grading** (`anonymous`, an instructor's switch): until the release, the grading queue and a
  submission's grading view show everyone who grades (the instructor too) "Student 3" (the roster's order),
  never the id or name; and a TA sees the label in every view of that assignment (the dashboard's rows, a
  student's detail, the submissions list, the statistics' students, the similarity report's pairs:
  `hides_names`, `anonymous_labels`).
  An instructor still sees names outside the queue: they keep the roster, extensions and tokens.
- **The release** (`release`, an instructor's): until it, the manual part reaches no student, no export and no
  LMS; after it, a grade is the auto part plus the manual part, the late penalty taken off the whole
  (server/course/grades.py `total`). Grades changed after the release reach them at once.

Each change goes through one method (`_set_manual_grade`, `_release`, `_set_graders`, `_set_anonymous`), which
records it in the audit trail in the change's own transaction (server/course/audit.py): `manual.grade` (the item's
points, levels, override and comment before and after), `assignment.release`, `manual.graders` ({student:
grader} before and after), `manual.anonymous` (a switch that changes it).
"""

from __future__ import annotations

import logging

from server.core.errors import Invalid, NotFound
from server.core.roles import Role
from server.course.audit import Target
from server.course.base import CourseBase, iso, status_of
from server.course.people import Who
from server.course.schema import AssignmentRow, ManualGrade, ManualGradeRow, ManualRow, SubmissionWithGrade

log = logging.getLogger(__name__)

MAX_COMMENT = 4000


class Manual(CourseBase):
    """Manual grades, the grading queue, graders, the release (mixed into server/course/service.Course)."""

    def manual_items(self, a: AssignmentRow) -> list:
        return self.spec(a["id"], a["version"]).manual

    def released_at(self, a: AssignmentRow) -> float | None:
        return self.store.manual_state(a["id"])["released_at"]

    def manual_points(self, a: AssignmentRow, item: str, row: ManualGrade) -> float:
        """One grade's points by the current spec: the override, or the chosen levels' sum, clamped to 0..the
        item's points (0 for an item the spec no longer has)."""
        m = self.spec(a["id"], a["version"]).manual_item(item)
        if m is None:
            return 0.0
        return m.score(row["rubric"]) if row["points"] is None else min(m.points, max(0.0, row["points"]))

    def manual_part(self, a: AssignmentRow, sid: str, rows: dict[str, ManualGradeRow] | None = None) -> dict:
        """A submission's manual grades by the current spec: {points, max_points, complete, items: [...]}."""
        if rows is None:
            rows = self.store.manual_grades(a["id"], sid).get(sid, {})
        items, total = [], 0.0
        for m in self.manual_items(a):
            row = rows.get(m.name)
            points = None
            if row is not None:
                points = self.manual_points(a, m.name, row)
                total += points
            items.append(
                {"name": m.name, "max_points": m.points, "points": points,
                 "rubric": row["rubric"] if row else [], "override": row["points"] if row else None,
                 "comment": row["comment"] if row else "", "grader": row["grader"] if row else None,
                 "graded_at": iso(row["graded_at"]) if row else None}
            )  # fmt: skip
        graded = [i for i in items if i["points"] is not None]
        return {"points": round(total, 6) if graded else None, "max_points": sum(i["max_points"] for i in items),
                "complete": len(graded) == len(items), "items": items}  # fmt: skip

    def released_manual(self, a: AssignmentRow, sub: SubmissionWithGrade) -> float | None:
        """The manual part of a submission that reaches students, exports and the LMS: its points once released
        (0 for an item not graded), None before the release or when the spec has no manual items."""
        if not self.manual_items(a) or self.released_at(a) is None:
            return None
        return self.manual_part(a, sub["id"])["points"] or 0.0

    def manual_view(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who) -> dict | None:
        """The manual part as the caller sees it: staff always; a student after the release ({released: false}
        before it); None when the spec has no manual items."""
        if not self.manual_items(a):
            return None
        released = self.released_at(a)
        if who.student is not None and released is None:
            return {"released": False}
        part = self.manual_part(a, sub["id"])
        if who.student is not None:
            for item in part["items"]:
                item.pop("grader")
        return {"released": released is not None, **part}

    # -- grading -------------------------------------------------------------------------------------------

    def set_manual_grade(self, a: AssignmentRow, sid: str, item: str, body: dict, who: Who) -> dict:
        """Grade one item of a submission (body: rubric [level names], points (an override or None), comment);
        422 naming the field for an unknown item or level, an override out of range."""
        sub = self.submission(a, sid)
        if sub is None:
            raise NotFound([{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
        spec_item = self.spec(a["id"], a["version"]).manual_item(item)
        if spec_item is None:
            names = ", ".join(repr(m.name) for m in self.manual_items(a)) or "none: the spec has no manual items"
            raise Invalid([{"path": "item", "message": f"no manual item {item[:100]!r}; the items: {names}"}])
        chosen = list(dict.fromkeys(body.get("rubric") or []))
        for i, name in enumerate(chosen):
            if spec_item.level(name) is None:
                levels = ", ".join(repr(r.name) for r in spec_item.rubric)
                message = f"no level {str(name)[:100]!r} in the rubric of {item!r}; its levels: {levels}"
                raise Invalid([{"path": f"rubric[{i}]", "message": message}])
        points = body.get("points")
        if points is not None and not 0 <= points <= spec_item.points:
            message = f"expected points within 0..{spec_item.points:g} (the item's); got {points:g}"
            raise Invalid([{"path": "points", "message": message}])
        comment = body.get("comment") or ""
        if len(comment) > MAX_COMMENT:
            raise Invalid([{"path": "comment", "message": f"at most {MAX_COMMENT} characters; got {len(comment)}"}])
        row: ManualGrade = {"rubric": chosen, "points": points, "comment": comment, "grader": who.person}
        self._set_manual_grade(a, sub, item, row, who)
        return self.grading_view(a, sub, who)

    def _set_manual_grade(
        self, a: AssignmentRow, sub: SubmissionWithGrade, item: str, row: ManualGrade, who: Who
    ) -> None:
        """The one write of a manual grade, audited (`manual.grade`) in its transaction."""
        target = Target(a["course_id"], a["id"], student=sub["student"], submission=sub["id"])
        self.store.set_manual(
            a["id"], sub["id"], item, row, self.now(), self.by(who), target, lambda r: self.manual_points(a, item, r)
        )
        log.info("manual grade of %s for submission %s by %s", item, sub["id"], row["grader"] or "the admin")
        if self.released_at(a) is not None:
            self._grade_moved(sub)

    def _grade_moved(self, sub: SubmissionWithGrade) -> None:
        """A student's grade moved without its grading run: the run's listeners told (the LMS poster, followers)."""
        for listener in list(self.runs.listeners):
            listener(sub["run_id"], sub["id"])

    def release(self, a: AssignmentRow, who: Who) -> dict:
        """The manual part released to the students, the exports and the LMS (again: the time moves)."""
        self._release(a, who)
        for _, _, c, _ in self.class_grades(a):
            if c is not None:
                self._grade_moved(c)
        return self.grading_state(a, who)

    def _release(self, a: AssignmentRow, who: Who) -> None:
        """The one write of a release, audited (`assignment.release`) in its transaction."""
        self.store.release_manual(a["id"], who.person, self.now(), self.by(who), Target(a["course_id"], a["id"]))
        log.info("manual grades of assignment %s released by %s", a["id"], who.person or "the admin")

    def set_anonymous(self, a: AssignmentRow, anonymous: bool, who: Who) -> ManualRow:
        self._set_anonymous(a, anonymous, who)
        return self.store.manual_state(a["id"])

    def _set_anonymous(self, a: AssignmentRow, anonymous: bool, who: Who) -> None:
        """The one write of anonymity, audited (`manual.anonymous`, when it changes) in its transaction."""
        self.store.set_anonymous(a["id"], anonymous, self.by(who), Target(a["course_id"], a["id"]))

    def assign_graders(self, a: AssignmentRow, graders: list[str], who: Who) -> dict:
        """The roster's students dealt to `graders` (staff ids of the course) in turn: as many each, within one."""
        staff = {s["person"] for s in self.store.staff(a["course_id"])}
        if not graders:
            raise Invalid([{"path": "graders", "message": "expected at least one grader (a staff id of the course)"}])
        for i, g in enumerate(graders):
            if g not in staff:
                message = f"no staff member {str(g)[:80]!r} in the course; its staff: {', '.join(sorted(staff))}"
                raise Invalid([{"path": f"graders[{i}]", "message": message}])
        graders = list(dict.fromkeys(graders))
        students = [st["student"] for st in self.store.students(a["id"])]
        pairs = [(s, graders[i % len(graders)]) for i, s in enumerate(students)]
        self._set_graders(a, pairs, who)
        counts = {g: sum(1 for _, x in pairs if x == g) for g in graders}
        return {"graders": [{"id": g, "students": n} for g, n in counts.items()]}

    def _set_graders(self, a: AssignmentRow, pairs: list[tuple[str, str]], who: Who) -> None:
        """The one write of the graders' assignment, audited (`manual.graders`) in its transaction."""
        self.store.set_graders(a["id"], pairs, self.by(who), Target(a["course_id"], a["id"]))

    # -- anonymity -------------------------------------------------------------------------------------------

    def hides_names(self, a: AssignmentRow, who: Who) -> bool:
        """Are students' names hidden from this caller now: anonymous grading on, not released, and a TA?"""
        if who.student is not None or who.role != Role.TA:
            return False
        state = self.store.manual_state(a["id"])
        return bool(state["anonymous"]) and state["released_at"] is None

    def anonymous_labels(self, a: AssignmentRow) -> dict[str, str]:
        """{student id: "Student N"} by the roster's order (the grading queue's labels)."""
        return {st["student"]: f"Student {i}" for i, st in enumerate(self.store.students(a["id"]), 1)}

    def anonymous_student(self, a: AssignmentRow, label: str) -> str | None:
        """The student a label stands for (None: no such label)."""
        return next((s for s, x in self.anonymous_labels(a).items() if x == label), None)

    # -- the queue -------------------------------------------------------------------------------------------

    def grading_state(self, a: AssignmentRow, who: Who) -> dict:
        """The release, anonymity and points; the course's staff (who may be assigned), the graders assigned
        (each with their number of students) and the caller's id (`you`)."""
        state = self.store.manual_state(a["id"])
        most = sum(m.points for m in self.manual_items(a))
        assigned = list(self.store.graders(a["id"]).values())
        graders = [{"id": g, "students": assigned.count(g)} for g in dict.fromkeys(assigned)]
        staff = [{"id": s["person"], "name": s["name"], "role": s["role"]} for s in self.store.staff(a["course_id"])]
        return {"released": state["released_at"] is not None, "released_at": iso(state["released_at"]),
                "anonymous": bool(state["anonymous"]), "max_points": most, "staff": staff, "graders": graders,
                "you": who.person}  # fmt: skip

    def queue(
        self, a: AssignmentRow, who: Who, grader: str | None = None, everyone: bool = False
    ) -> list[SubmissionWithGrade]:
        """The counting submissions still to grade (some item without a grade), in the roster's order: the
        grader's own when graders are assigned (`grader`, else the caller's; the admin, an unassigned caller and
        `everyone`: everyone's)."""
        assigned = self.store.graders(a["id"])
        mine = grader if grader is not None else (who.person if who.person in set(assigned.values()) else None)
        mine = None if everyone else mine
        grades = self.store.manual_grades(a["id"])
        items = {m.name for m in self.manual_items(a)}
        out = []
        for st, _, c, _ in self.class_grades(a):
            if c is None or (mine is not None and assigned.get(st["student"]) != mine):
                continue
            if not items <= set(grades.get(c["id"], {})):
                out.append(c)
        return out

    def next_to_grade(
        self, a: AssignmentRow, who: Who, grader: str | None = None, after: str | None = None, everyone: bool = False
    ) -> dict | None:
        """The next submission to grade (after `after` in the queue's order, wrapping; `everyone`'s), or None."""
        todo = self.queue(a, who, grader, everyone)
        if not todo:
            return None
        ids = [c["id"] for c in todo]
        start = ids.index(after) + 1 if after in ids else 0
        if after is not None and after not in ids:  # graded since: the first one after it in the roster's order
            order = [c["id"] for _, _, c, _ in self.class_grades(a) if c is not None]
            later = order[order.index(after) + 1 :] if after in order else []
            start = next((ids.index(s) for s in later if s in ids), 0)
        view = self.grading_view(a, todo[start % len(todo)], who)
        view["remaining"] = len(todo)
        return view

    def grading_view(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who) -> dict:
        """What the grading queue shows of a submission: who (or an anonymous label), the pictures, the scene,
        the auto part, the rubric and the grades so far."""
        state = self.store.manual_state(a["id"])
        hidden = bool(state["anonymous"]) and state["released_at"] is None
        roster = [st["student"] for st in self.store.students(a["id"])]
        number = roster.index(sub["student"]) + 1 if sub["student"] in roster else 0
        member = self.store.student(a["id"], sub["student"])
        base = f"/api/assignments/{a['id']}"
        auto = self.view(a, sub, who)
        files = auto.get("files") or {}
        return {
            "submission": sub["id"],
            "student": None if hidden else {"id": sub["student"], "name": member["name"] if member else sub["student"]},
            "label": f"Student {number}" if hidden else (member["name"] if member else sub["student"]),
            "kind": sub["kind"],
            "render": files.get("render.png"),
            "reference": files.get("reference.png") or f"{base}/reference.png",
            "scene": f"{base}/grading/submissions/{sub['id']}/scene.json" if sub["kind"] == "scene" else None,
            "auto": {"status": status_of(sub), "score": auto["score"], "max_score": auto["max_score"],
                     "late": auto["late"], "feedback": auto["feedback"]},
            "items": [m.model_dump() for m in self.manual_items(a)],
            "manual": self.manual_part(a, sub["id"]),
            "url": f"{base}/grading/submissions/{sub['id']}",
        }  # fmt: skip

    def scene_text(self, a: AssignmentRow, sub: SubmissionWithGrade) -> bytes | None:
        """A scene submission's file as the student sent it (None for an image)."""
        if sub["kind"] != "scene":
            return None
        path = self.root / sub["file"]
        return path.read_bytes() if path.is_file() else None
