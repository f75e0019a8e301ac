"""Class statistics of an assignment (server/course/stats.py, docs/assignments.md "Class statistics"): the
score distribution, each test's pass rate, attempts and time to full marks per student, as JSON for the
dashboard and as CSV. The course's staff only, as the dashboard: a student's token gets the 404 of an unknown
id, anyone else 401 or 403. Before assignments.py, whose routes would not take these paths but whose prefix
is the same. Plain functions: FastAPI runs them in its threads (they read the database and files)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from server.api.deps import CallerDep, CourseDep, instructor_check
from server.api.models import ErrorResponse, Responses
from server.core.security import Caller
from server.course import stats
from server.course.schema import AssignmentRow
from server.course.service import Course

router = APIRouter(prefix="/api/assignments", tags=["assignments"])
REFUSED: Responses = {
    403: {"model": ErrorResponse, "description": "a token of no staff of the assignment's course"},
    404: {"model": ErrorResponse, "description": "no such assignment (or a student's token)"},
}


def _staff(course: Course, aid: str, caller: Caller, request: Request) -> AssignmentRow:
    return course.staff(aid, caller, instructor_check(request), "follow")[0]


@router.get("/{aid}/stats", summary="The class's statistics (the course's staff)", responses=REFUSED)
def class_stats(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """`{students, graded, max_points, histogram: {bins: [{from, to, count}], mean, median}, tests: [{test,
    name, kind, graded, passed, failed, rate}], fails_most: [...], attempts: {mean, median, max, students:
    [{attempts, students}]}, full_marks: {students, submitted, median_seconds}, per_student: [{id, name, state,
    points, submissions, attempts, first_at, full_marks_at, to_full_marks}]}`: each student's counting
    submission as the dashboard and the grades have it; times in seconds. Under anonymous grading, until the
    release, a TA's per_student has the grading queue's labels for ids and names (server/course/manual.py)."""
    a, who = course.staff(aid, caller, instructor_check(request), "follow")
    out = stats.stats(course, a)
    if course.hides_names(a, who):
        labels = course.anonymous_labels(a)
        out["per_student"] = [{**r, "id": labels.get(r["id"], "Student ?"), "name": labels.get(r["id"], "Student ?")}
                              for r in out["per_student"]]  # fmt: skip
    return out


@router.get("/{aid}/stats.csv", summary="The class's statistics, one row per student (CSV)", responses=REFUSED)
def class_stats_csv(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """id, name, state, points, max_points, submissions, attempts, first_submitted, full_marks_at,
    hours_to_full_marks, then `test: <name>` per test of the spec (passed, failed or empty)."""
    text = stats.stats_csv(course, _staff(course, aid, caller, request))
    headers = {"Content-Disposition": 'attachment; filename="stats.csv"', "Cache-Control": "no-store"}
    return Response(text, media_type="text/csv", headers=headers)
