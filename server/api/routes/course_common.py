"""What the course's routers share (assignments.py, roster.py, submissions.py, dashboard.py, courses.py): the
error answers they document, the server's base URL for links, the assignment for its staff, a roster body as
text and a CSV download."""

from __future__ import annotations

from typing import Annotated

from fastapi import Query, Request, Response

from server.api.deps import (
    instructor_check,
)
from server.api.errors import ApiError
from server.api.models import ErrorResponse, Responses
from server.core.security import Caller
from server.course.people import Who
from server.course.schema import AssignmentRow
from server.course.service import Course

ERRORS: Responses = {
    422: {"model": ErrorResponse, "description": "a field that is wrong, named with what was expected"}
}

# why a change is made, for its audit event (server/course/audit.py)
Why = Annotated[str, Query(max_length=1000, description="why (kept in the course's audit trail)")]

NOT_FOUND: Responses = {404: {"model": ErrorResponse, "description": "no such assignment (or not yours)"}}


def base_url(request: Request) -> str:
    return str(request.base_url)


def staff_assignment(
    course: Course, aid: str, caller: Caller, request: Request, action: str = "follow"
) -> AssignmentRow:
    """The assignment, for its course's staff only (a TA for what a TA may do, else 403): its students' tokens
    get the 404 of an unknown id (on a server where everyone is the instructor too), anyone else 401 or 403."""
    return course.staff(aid, caller, instructor_check(request), action)[0]


def staff_who(course: Course, aid: str, caller: Caller, request: Request, action: str = "follow") -> Who:
    """The caller as the assignment's staff (refused as `staff_assignment` refuses): who a change is by."""
    return course.staff(aid, caller, instructor_check(request), action)[1]


async def roster_text(request: Request) -> str:
    """A roster upload's body as text (422 unless it is UTF-8)."""
    try:
        return (await request.body()).decode("utf-8")
    except UnicodeDecodeError:
        raise ApiError(422, [{"path": "", "message": "the roster must be UTF-8 text (CSV)"}]) from None


def csv_response(text: str, filename: str) -> Response:
    """A CSV export, downloaded as `filename` and never cached (links carry tokens, grades are private)."""
    headers = {"Content-Disposition": f'attachment; filename="{filename}"', "Cache-Control": "no-store"}
    return Response(text, media_type="text/csv", headers=headers)
