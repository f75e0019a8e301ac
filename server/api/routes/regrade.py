"""Regrade requests (server/course/regrade.py, docs/assignments.md "Regrade requests"): a student asks about one
item of their counting submission; the course's staff (instructors and TAs) list the queue and answer. A student
sees their own requests only; another student's submission is the 404 of an unknown id. Before submissions.py
(its /{sid}/{name})."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query, Request
from pydantic import BaseModel, ConfigDict, Field

from server.api.deps import CallerDep, CourseDep
from server.api.models import ErrorResponse
from server.api.routes.course_common import ERRORS, NOT_FOUND, staff_assignment, staff_who
from server.course.regrade import MAX_REASON, MAX_REPLY

router = APIRouter(prefix="/api/assignments", tags=["assignments"])
REFUSED = {
    **NOT_FOUND,
    403: {"model": ErrorResponse, "description": "past the regrade deadline, an item not shown yet, or not the "
          "caller's to ask or answer"},
    409: {"model": ErrorResponse, "description": "not the student's counting submission, or a request open already"},
}  # fmt: skip


class RegradeIn(BaseModel):
    """A student's request about one item of their counting submission."""

    model_config = ConfigDict(extra="forbid")
    item: str = Field(min_length=1, max_length=200, description="A test's name (validity, a requirement's name, "
                      "an image test: flip, ssim, psnr, pixels) or a staff-graded item's name.")  # fmt: skip
    reason: str = Field(min_length=1, max_length=MAX_REASON, description="What should be looked at again, and why.")


class AnswerIn(BaseModel):
    """Staff's answer to a request (again: each answer kept)."""

    model_config = ConfigDict(extra="forbid")
    status: Literal["accepted", "declined"]
    reply: str = Field(min_length=1, max_length=MAX_REPLY, description="For the student.")
    points: float | None = Field(None, description="Accepted only: the item's new points (0..its most).")


@router.post(
    "/{aid}/submissions/{sid}/regrade-requests",
    status_code=201,
    summary="Ask for a regrade of one item of your counting submission (the student's)",
    responses={**ERRORS, **REFUSED},
)
def ask(aid: str, sid: str, body: RegradeIn, course: CourseDep, caller: CallerDep) -> dict:
    """201 with the request: `{id, submission, item, kind (test or manual), reason, status: open, reply, points
    (the item's now), max_points, asked_at, answered_at, history, url}`. 403 naming `regrade_deadline` after it,
    `item` for a result not shown yet; 409 naming `sid` for a submission that is not the grade, `item` when one is
    open for it; 422 naming `item` for an unknown item."""
    a, who = course.who(aid, caller)
    return course.request_regrade(a, sid, body.model_dump(), who)


@router.get(
    "/{aid}/regrade-requests",
    summary="The regrade requests: staff, the queue; a student, their own",
    responses={**ERRORS, **NOT_FOUND},
)
def queue(
    aid: str,
    course: CourseDep,
    caller: CallerDep,
    status: Annotated[str | None, Query(max_length=20, description="open, accepted or declined")] = None,
) -> dict:
    """`{requests: [...], regrade_deadline, regrade_open}` (the last two a student's): open first, then oldest
    first; to staff each also with `student` ({id, name}, or null while the assignment grades anonymously and is not
    released), `label`, `answered_by`."""
    a, who = course.who(aid, caller)
    return course.regrade_requests(a, who, status)


@router.get(
    "/{aid}/submissions/{sid}/regrade-requests",
    summary="One submission's regrade requests (its student, or staff)",
    responses={**ERRORS, **NOT_FOUND},
)
def of_submission(aid: str, sid: str, course: CourseDep, caller: CallerDep) -> dict:
    a, who = course.who(aid, caller)
    return course.regrade_requests(a, who, sid=sid)


@router.put(
    "/{aid}/submissions/{sid}/regrade-requests/{rid}",
    summary="Answer a regrade request: accepted (with points) or declined, with a reply (the course's staff)",
    responses={**ERRORS, **REFUSED},
)
def answer(aid: str, sid: str, rid: str, body: AnswerIn, request: Request, course: CourseDep,
           caller: CallerDep) -> dict:  # fmt: skip
    """The request with its history. Accepted with `points`: that item's points for that submission (a manual
    item's grade overridden, or a test's points in the auto part): the totals, exports and LMS follow."""
    a = staff_assignment(course, aid, caller, request, "grade")
    who = staff_who(course, aid, caller, request, "grade")
    return course.answer_regrade(a, sid, rid, body.model_dump(), who)
