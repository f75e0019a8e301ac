"""The instructor's view of an assignment's class (web/course.html; server/course/dashboard.py): the dashboard,
one student's history, and the grades as CSV (the grades, an LMS gradebook's columns)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from server.api.deps import (
    CallerDep,
    CourseDep,
    MaybeLmsDep,
    instructor_check,
)
from server.api.errors import ApiError
from server.api.routes.course_common import NOT_FOUND, csv_response, staff_assignment
from server.course import dashboard as course_board
from server.course import owntrees

router = APIRouter(prefix="/api/assignments", tags=["assignments"])


@router.get("/{aid}/grades.csv", summary="The grades: one row per roster student", responses=NOT_FOUND)
def grades(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    return csv_response(course.grades_csv(staff_assignment(course, aid, caller, request)), "grades.csv")


@router.get("/{aid}/gradebook.csv", summary="The grades as an LMS gradebook imports them", responses=NOT_FOUND)
def gradebook(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """Canvas's gradebook columns (Student, ID, SIS User ID, SIS Login ID, Section, the assignment) and a
    Points Possible row: the roster's id is the SIS User ID, its email the SIS Login ID."""
    return csv_response(course.gradebook_csv(staff_assignment(course, aid, caller, request)), "gradebook.csv")


@router.get(
    "/{aid}/dashboard", summary="The roster with each student's state and score (the instructor's)", responses=NOT_FOUND
)
def dashboard(aid: str, request: Request, course: CourseDep, caller: CallerDep, lms: MaybeLmsDep) -> dict:
    """Every roster student with their deadline (an extension marked), state (none, submitted, graded,
    invalid, failed), counting score, submissions and whether self-declared; and the class's counts, mean and
    median. One answer for the whole class, for a page that follows it while it submits."""
    a, who = course.staff(aid, caller, instructor_check(request))
    out = course_board.dashboard(course, a)
    if course.hides_names(a, who):  # anonymous grading: a TA sees the queue's labels (server/course/manual.py)
        labels = course.anonymous_labels(a)
        out["students"] = [course_board.masked(r, labels.get(r["id"], "Student ?")) for r in out["students"]]
    out["tree_whats"] = owntrees.whats(course, a)  # own tracers: the class's first differences by `what`
    out["lms"] = lms.board(aid, a["course_id"]) if lms is not None else None
    out["course"] = a["course_id"]
    return out


@router.get(
    "/{aid}/students/{student}",
    summary="One student: their state and every submission (the instructor's)",
    responses=NOT_FOUND,
)
def student_detail(aid: str, student: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """The student's dashboard row and their history: each submission as GET .../submissions/{sid} shows it
    to the instructor (status, late, score, feedback, pictures), oldest first."""
    a, who = course.staff(aid, caller, instructor_check(request))
    hidden = course.hides_names(a, who)  # anonymous grading: a TA names the student by their label
    out = course_board.student_detail(course, a, course.anonymous_student(a, student) or "" if hidden else student)
    if out is not None and hidden:
        out = course_board.masked(out, student)
    if out is None:
        raise ApiError(404, [{"path": "student", "message": f"no student '{student[:80]}' on the roster"}])
    return out
