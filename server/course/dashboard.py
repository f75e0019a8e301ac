"""The instructor's dashboard of one assignment (web/course.html): the roster joined with each student's
state in one answer, so that a page following a class of 300 while it submits asks once every few seconds
rather than once per student.

A student's **state** is what the roster column says of them:
- `none`: nothing submitted;
- `submitted`: something is waiting to be graded (queued or grading) and nothing of theirs is graded yet;
- `graded`: a graded submission counts (the last or the best, as the policy says); `pending` tells whether
  a newer one is still waiting;
- `invalid`: every submission was invalid (its scene did not validate, its image could not be read);
- `failed`: nothing graded, and a submission could not be graded (it costs no attempt).

`score` is the counting submission's after the late penalty (as grades.csv has it), `max_score` its own
maximum (a scene's 13 or an image's 7 in the example), and `points` the score scaled to the spec's points
(as gradebook.csv has it), which the distribution uses: scenes and images then share one axis.

With staff-graded items (server/course/manual.py) a row also has `manual` (the graded items' points so far, None
when none is graded), `released` (the manual part released to the students), `total` and `total_max` (the auto
part plus the manual part graded so far, the late penalty taken off the whole: grades.csv's score and max_score
once released), and `points` counts the manual part too (so do the mean, the median and the statistics, out of
the spec's points plus the items'): staff see the manual part as it is graded, marked "not released" until the
release.
"""

from __future__ import annotations

import statistics

from server.course.base import iso, status_of
from server.course.people import Who
from server.course.schema import AssignmentRow, ManualGradeRow, SubmissionWithGrade
from server.course.service import Course

PENDING = ("queued", "grading")


def student_rows(course: Course, a: AssignmentRow) -> list[dict]:
    """Each roster student with their deadline, state, counting score and submissions, in roster order."""
    spec = course.spec(a["id"], a["version"])
    points = spec.max_score()
    manual = course.store.manual_grades(a["id"]) if spec.manual else {}
    released = bool(spec.manual) and course.released_at(a) is not None
    rows = []
    for st, mine, counting, score in course.class_grades(a):
        statuses = [status_of(s) for s in mine]
        pending = sum(x in PENDING for x in statuses)
        if counting is not None:
            state = "graded"
        elif pending:
            state = "submitted"
        elif not mine:
            state = "none"
        elif all(x == "invalid" for x in statuses):
            state = "invalid"
        else:
            state = "failed"
        due, cut = course.deadlines(a, st)
        rows.append(
            {
                "id": st["student"],
                "name": st["name"],
                "email": st["email"],
                "self_declared": bool(st["self_declared"]),
                "active": st["left_at"] is None,  # False: gone from the LMS course (kept; cannot submit)
                "deadline": iso(due),
                "late_until": iso(cut) if cut > due else None,
                "extended": st["deadline"] is not None,
                "state": state,
                "pending": pending,
                "submissions": len(mine),
                "late": bool(counting["late"]) if counting is not None else any(s["late"] for s in mine),
                "score": None if score is None else round(score, 6),
                "max_score": counting["max_score"] if counting is not None else None,
                "points": None
                if score is None or counting is None
                else round(score * points / (counting["max_score"] or points), 6),
                "counting": counting["id"] if counting is not None else None,
                "last_at": iso(mine[-1]["accepted_at"]) if mine else None,
            }
        )
        if spec.manual:
            _with_manual(course, a, rows[-1], counting, manual, released)
    return rows


def _with_manual(
    course: Course,
    a: AssignmentRow,
    row: dict,
    counting: SubmissionWithGrade | None,
    grades: dict[str, dict[str, ManualGradeRow]],
    released: bool,
) -> None:
    """A row's manual part (see the module's docstring): `manual`, `released`, `total`, `total_max`, `points`."""
    spec = course.spec(a["id"], a["version"])
    part = None if counting is None else course.manual_part(a, counting["id"], grades.get(counting["id"], {}))
    row["manual"] = None if part is None else part["points"]
    row["released"] = released
    row["total"] = row["total_max"] = None
    if counting is not None:
        keep = 1 - (a["policy"]["late_penalty"] if counting["late"] else 0.0)
        extra = (row["manual"] or 0.0) * keep
        row["total"] = round(row["score"] + extra, 6)
        row["total_max"] = (counting["max_score"] or 0) + spec.manual_points()
        row["points"] = round(row["points"] + extra, 6)


def max_points(course: Course, a: AssignmentRow) -> float:
    """The rows' `points` out of: the spec's points, plus its manual items' (counted as graded)."""
    spec = course.spec(a["id"], a["version"])
    return spec.max_score() + (spec.manual_points() if spec.manual else 0)


def dashboard(course: Course, a: AssignmentRow) -> dict:
    """The assignment's dashboard: its students (student_rows) and the counts, mean and median of the class
    (in the spec's points, over the students with a graded submission). `submitted`: students who submitted
    anything; `waiting`: those with a submission not graded yet; `graded`, `invalid`, `failed`: by state."""
    rows = student_rows(course, a)
    graded = [r["points"] for r in rows if r["points"] is not None]
    counts = {k: sum(r["state"] == k for r in rows) for k in ("none", "submitted", "graded", "invalid", "failed")}
    return {
        "id": a["id"],
        "version": a["version"],
        "name": a["spec"]["name"],
        "max_points": max_points(course, a),
        "released": None if not course.manual_items(a) else course.released_at(a) is not None,
        "deadline": a["policy"]["deadline"],
        "now": iso(course.now()),
        "students": rows,
        "summary": {
            "students": len(rows),
            "submitted": len(rows) - counts["none"],
            "not_submitted": counts["none"],
            "waiting": sum(r["pending"] > 0 for r in rows),
            "late": sum(r["late"] for r in rows),
            "graded": counts["graded"],
            "invalid": counts["invalid"],
            "failed": counts["failed"],
            "mean": round(statistics.fmean(graded), 6) if graded else None,
            "median": round(statistics.median(graded), 6) if graded else None,
        },
    }


def masked(row: dict, label: str) -> dict:
    """A dashboard row or a student's detail as a TA sees it under anonymous grading: the label for the id and the
    name, no email, the label in each submission and in the tokens."""
    out = {**row, "id": label, "name": label, "email": None, "anonymous": True}
    if "history" in row:
        out["history"] = [{**v, "student": label} for v in row["history"]]
        out["tokens"] = {**row["tokens"], "student": label}
    return out


def student_detail(course: Course, a: AssignmentRow, student: str) -> dict | None:
    """One student's row (as student_rows) and every submission of theirs, as the instructor sees it
    (feedback whole, pictures listed), oldest first, their extensions' history and their late tokens. None for a
    student not on the roster."""
    row = next((r for r in student_rows(course, a) if r["id"] == student), None)
    if row is None:
        return None
    subs = course.submissions(a, student)
    who = Who(None)
    return {
        **row,
        "history": [course.view(a, s, who, row["counting"]) for s in subs],
        "extensions": course.extension_history(a["id"], student),  # each grant: at, who, before, after, why
        "tokens": course.tokens_of(a["course_id"], student),  # late tokens: left, granted, spent, each grant
        "course": a["course_id"],
    }
