"""The course's pages: HTML files of web/ served at paths that carry an id, which the static mount cannot.

GET /assignments/{id} is the student's view of one assignment (web/assignment.html). The link a student is
mailed is this path with `#token=...`: the fragment never reaches the server, so the page reads the token
itself. GET /course is the instructor's (web/course.html): their assignments, publishing, and one
assignment's dashboard at /course#<id>.
"""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import FileResponse

from server.core.paths import WEB

router = APIRouter(include_in_schema=False)


@router.get("/assignments/{aid}")
def student_view(aid: str) -> FileResponse:  # the id is read by the page from its own address
    return FileResponse(WEB / "assignment.html", media_type="text/html")


@router.get("/course")
def instructor_view() -> FileResponse:
    return FileResponse(WEB / "course.html", media_type="text/html")


@router.get("/courses/{cid}")
def student_course_view(cid: str) -> FileResponse:  # a student's course page: their assignments (web/mycourse.html)
    return FileResponse(WEB / "mycourse.html", media_type="text/html")
