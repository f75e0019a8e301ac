"""Grades and their exports: the submission that counts (the last graded one, or the best after the late penalty),
the class's grades, the grades CSV, an LMS gradebook's CSV and Gradescope's results.json."""

from __future__ import annotations

import io
import json
from typing import cast

from server.course.base import CourseBase, report_keys, status_of
from server.course.policy import Feedback, When
from server.course.schema import AssignmentRow, StudentRow, SubmissionWithGrade
from tracer.tools import spreadsheet

VISIBILITY = {When.now: "visible", When.after_deadline: "after_due_date", When.never: "hidden"}  # Gradescope's


class Grades(CourseBase):
    """The counting submission, the class's grades, the exports (mixed into server/course/service.Course)."""

    def counting(self, a: AssignmentRow, subs: list[SubmissionWithGrade]) -> SubmissionWithGrade | None:
        """The submission that is the grade: the last graded one, or the best (by the share of its points
        after the late penalty; the later of two equal ones)."""
        graded = [s for s in subs if status_of(s) == "graded" and s["score"] is not None]
        if not graded:
            return None
        if a["policy"]["counts"] == "last":
            return graded[-1]
        penalty = a["policy"]["late_penalty"]

        def share(s: SubmissionWithGrade) -> float:
            return cast(float, s["score"]) * (1 - (penalty if s["late"] else 0)) / (s["max_score"] or 1)  # graded

        return max(reversed(graded), key=share)

    def class_grades(
        self, a: AssignmentRow
    ) -> list[tuple[StudentRow, list[SubmissionWithGrade], SubmissionWithGrade | None, float | None]]:
        """Each roster student: (their row, their submissions in order, the counting submission or None, its
        score after the late penalty or None), in the roster's order."""
        subs: dict[str, list[SubmissionWithGrade]] = {}
        for s in self.submissions(a):
            subs.setdefault(s["student"], []).append(s)
        out = []
        for st in self.store.students(a["id"]):
            mine = subs.get(st["student"], [])
            c = self.counting(a, mine)
            penalty = a["policy"]["late_penalty"] if c is not None and c["late"] else 0.0
            out.append((st, mine, c, None if c is None else cast(float, c["score"]) * (1 - penalty)))
        return out

    def total(self, a: AssignmentRow, sub: SubmissionWithGrade) -> tuple[float, float]:
        """(the grade, its maximum) of a graded submission as students, exports and the LMS see it: the auto part
        plus the manual part once released (server/course/manual.py), the late penalty taken off the whole."""
        penalty = a["policy"]["late_penalty"] if sub["late"] else 0.0
        score, most = cast(float, sub["score"]), cast(float, sub["max_score"])  # graded: neither is None
        manual = self.released_manual(a, sub)
        if manual is None:
            return score * (1 - penalty), most
        return (score + manual) * (1 - penalty), (most or 0) + self.spec(a["id"], a["version"]).manual_points()

    def final_grades(self, a: AssignmentRow) -> list[tuple[StudentRow, SubmissionWithGrade | None, float | None, int]]:
        """Each roster student: (their row, the counting submission or None, its score after the late
        penalty or None, how many submissions they made), in the roster's order."""
        return [(st, c, score, len(mine)) for st, mine, c, score in self.class_grades(a)]

    def grades_csv(self, a: AssignmentRow) -> str:
        """One row per roster student: id, name, score (the counting submission's, late penalty applied; empty
        when none was graded; with the manual part once released: `total`), max_score, late, submissions (all
        they made)."""
        buf = io.StringIO()
        w = spreadsheet.writer(buf, lineterminator="\n")
        w.writerow(["id", "name", "score", "max_score", "late", "submissions"])
        for st, c, score, n in self.final_grades(a):
            if c is None:
                w.writerow([st["student"], st["name"], "", "", "", n])
            else:
                late = "true" if c["late"] else "false"
                score, most = self.total(a, c)
                w.writerow([st["student"], st["name"], _num(score), _num(most), late, n])
        return buf.getvalue()

    def gradebook_csv(self, a: AssignmentRow) -> str:
        """The grades as a learning management system imports them (Canvas's gradebook columns: Student, ID,
        SIS User ID, SIS Login ID, Section, then one column for this assignment, and a Points Possible row):
        the roster's id as the SIS User ID, its email as the SIS Login ID; a student with nothing graded has
        an empty cell, which an import leaves as it was. The column has one number of points (the spec's), so
        a score out of another maximum (an image: no requirements) is scaled to it: 3.5 of 7 is 6.5 of 13. Once
        the manual part is released, its points are added to the column's and to each grade (not scaled)."""
        spec = self.spec(a["id"], a["version"])
        buf = io.StringIO()
        w = spreadsheet.writer(buf, lineterminator="\n")
        w.writerow(["Student", "ID", "SIS User ID", "SIS Login ID", "Section", f"{spec.name} ({a['id'][:8]})"])
        points = spec.max_score()
        released = spec.manual and self.released_at(a) is not None
        w.writerow(["Points Possible", "", "", "", "", _num(points + (spec.manual_points() if released else 0))])
        for st, c, score, _ in self.final_grades(a):
            scaled = None if c is None or score is None else score * points / (c["max_score"] or points)
            if scaled is not None and c is not None and released:
                penalty = a["policy"]["late_penalty"] if c["late"] else 0.0
                scaled += (self.released_manual(a, c) or 0.0) * (1 - penalty)
            w.writerow([st["name"], "", st["student"], st.get("email") or "", "", _num(scaled)])
        return buf.getvalue()

    def gradescope(self, a: AssignmentRow, sub: SubmissionWithGrade) -> dict | None:
        """A graded submission as Gradescope's autograder results.json (for an autograder that hands a
        student's work to this service and reports what it says): each test's visibility from the feedback
        policy (now: visible, after the deadline: after_due_date, never: hidden), the score after the late
        penalty, and the whole result's visibility that of the score. None before it is graded."""
        path = self.runs.root / sub["run_id"] / "out" / sub["id"] / "results.json"
        if sub.get("stage") != "graded" or not path.is_file():
            return None
        results = json.loads(path.read_text())
        feedback = Feedback.model_validate(a["policy"]["feedback"])
        keys = report_keys(self.spec(a["id"], sub["version"]), sub["kind"])
        for key, test in zip(keys, results.get("tests", []), strict=False):
            test["visibility"] = VISIBILITY[When(feedback.tests.get(key, feedback.default))]
        results["visibility"] = VISIBILITY[When(feedback.score_when())]
        if sub["late"] and a["policy"]["late_penalty"]:
            penalty = a["policy"]["late_penalty"]
            results["score"] = round(results["score"] * (1 - penalty), 6)
            results["output"] += f"\nlate: {penalty:g} of the points taken off"
        return results


def _num(x: float | None) -> str:
    return "" if x is None else f"{round(x, 6):g}"
