"""What the course's routers share (assignments.py, roster.py, submissions.py, dashboard.py, courses.py): the
error answers they document, the server's base URL for links, the assignment for its staff, a roster body as
text and a CSV download."""

from __future__ import annotations

from fastapi import Request, Response

from server.api.deps import (
    instructor_check,
)
from server.api.errors import ApiError
from server.api.models import ErrorResponse
from server.core.security import Caller
from server.course.service import Course

ERRORS = {422: {"model": ErrorResponse, "description": "a field that is wrong, named with what was expected"}}

NOT_FOUND = {404: {"model": ErrorResponse, "description": "no such assignment (or not yours)"}}


def base_url(request: Request) -> str:
    return str(request.base_url)


def staff_assignment(course: Course, aid: str, caller: Caller, request: Request, action: str = "follow") -> dict:
    """The assignment, for its course's staff only (a TA for what a TA may do, else 403): its students' tokens
    get the 404 of an unknown id (on a server where everyone is the instructor too), anyone else 401 or 403."""
    return course.staff(aid, caller, instructor_check(request), action)[0]


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
