"""The course's audit trail (server/course/audit.py, docs/assignments.md "The audit trail"): every change to a grade,
an extension, an assignment, the roster or the staff, newest first, as JSON or CSV. The course's staff only (its
TAs too, and the admin): a student's token, or a token of another course, gets the 404 of an unknown course, as
the course's other staff routes answer. Plain functions: FastAPI runs them in its threads (they read the
database)."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query, Request, Response

from server.api.deps import CallerDep, CourseDep, instructor_check
from server.api.models import ErrorResponse, Responses
from server.api.routes.course_common import csv_response
from server.course import audit
from server.course.schema import AuditEvent

router = APIRouter(prefix="/api/courses", tags=["courses"])
REFUSED: Responses = {
    403: {"model": ErrorResponse, "description": "a token of no one the server knows (or no admin token)"},
    404: {"model": ErrorResponse, "description": "no such course (or not yours: a student's, another course's)"},
    422: {"model": ErrorResponse, "description": "a query parameter that is wrong, named with what was expected"},
}
CSV_PAGES = 20  # a CSV export holds at most CSV_PAGES * audit.MAX_LIMIT events (the newest; page on with `before`)

Student = Annotated[str | None, Query(max_length=80, description="only events about this student (the roster's id)")]
Assignment = Annotated[str | None, Query(max_length=64, description="only events about this assignment (its id)")]
Limit = Annotated[int, Query(ge=1, le=audit.MAX_LIMIT, description=f"at most this many (1 to {audit.MAX_LIMIT})")]
Before = Annotated[int | None, Query(ge=1, description="events older than this id (the last page's `next`)")]
Format = Annotated[Literal["json", "csv"], Query(description="csv: the same events as CSV (audit.csv)")]


@router.get("/{cid}/audit", summary="The course's audit trail (its staff)", responses=REFUSED)
def trail(
    cid: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    student: Student = None,
    assignment: Assignment = None,
    limit: Limit = audit.DEFAULT_LIMIT,
    before: Before = None,
    format: Format = "json",  # noqa: A002 (the query parameter's name)
):
    """`{"events": [{id, at, who, action, target: {course, assignment?, student?, submission?, staff?}, before,
    after, why}], "next": id | null}`, newest first: `next` is the `before` of the next page (null: no more).
    `format=csv` answers CSV as audit.csv does."""
    if format == "csv":
        return trail_csv(cid, request, course, caller, student, assignment, before)
    course.course_staff(cid, caller, instructor_check(request))
    events = course.audit_trail(cid, student=student, assignment=assignment, limit=limit + 1, before=before)
    more = len(events) > limit
    events = events[:limit]
    return {"events": events, "next": events[-1]["id"] if more else None}


@router.get("/{cid}/audit.csv", summary="The course's audit trail as CSV (its staff)", responses=REFUSED)
def trail_csv(
    cid: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    student: Student = None,
    assignment: Assignment = None,
    before: Before = None,
) -> Response:
    """id, at, who, action, course, assignment, student, target, before, after, why (before, after and the
    target as JSON text); newest first; every cell formula-safe. The newest 10 000 events that match (`before`
    for older ones)."""
    course.course_staff(cid, caller, instructor_check(request))
    rows: list[AuditEvent] = []
    for _ in range(CSV_PAGES):
        page = course.audit_trail(cid, student=student, assignment=assignment, limit=audit.MAX_LIMIT, before=before)
        rows += page
        if len(page) < audit.MAX_LIMIT:
            break
        before = page[-1]["id"]
    return csv_response(audit.events_csv(rows), "audit.csv")
