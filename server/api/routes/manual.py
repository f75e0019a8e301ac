"""Staff-graded items (server/course/manual.py, docs/assignments.md "Staff-graded items"): a manual grade of one
item of a submission, the grading queue's next submission, the graders assigned, anonymous grading, the release.
The course's staff grade (a TA too); an instructor assigns graders, switches anonymity and releases. A student's
token gets the 404 of an unknown id, anyone else 401 or 403. Before submissions.py (its /{sid}/{name})."""

from __future__ import annotations

from fastapi import APIRouter, Query, Request, Response
from pydantic import BaseModel, ConfigDict, Field

from server.api.deps import CallerDep, CourseDep, instructor_check
from server.api.errors import ApiError
from server.api.models import ErrorResponse, Responses
from server.api.routes.course_common import ERRORS, NOT_FOUND
from server.core.security import Caller
from server.course.manual import MAX_COMMENT
from server.course.schema import AssignmentRow, SubmissionWithGrade
from server.course.service import Course

router = APIRouter(prefix="/api/assignments", tags=["assignments"])
REFUSED: Responses = {
    **NOT_FOUND,
    403: {"model": ErrorResponse, "description": "a token of no staff of the course (or a TA where an instructor is"
          " needed)"},
}  # fmt: skip


class ManualIn(BaseModel):
    """A grade of one manual item: the chosen rubric levels by name, an override of the points, a comment."""

    model_config = ConfigDict(extra="forbid")
    rubric: list[str] = Field(default_factory=list, max_length=9, description="The chosen levels' names.")
    points: float | None = Field(None, description="An override (0..the item's points); null: the levels' sum.")
    comment: str = Field("", max_length=MAX_COMMENT, description="For the student, shown after the release.")


class GradersIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    graders: list[str] = Field(min_length=1, max_length=200, description="Staff ids of the course.")


class GradingSettingsIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    anonymous: bool = Field(description="Students' names hidden from graders until the release.")


def _staff(course: Course, aid: str, caller: Caller, request: Request, action: str = "grade"):
    return course.staff(aid, caller, instructor_check(request), action)


def _sub(course: Course, a: AssignmentRow, sid: str) -> SubmissionWithGrade:
    sub = course.submission(a, sid)
    if sub is None:
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
    return sub


@router.put(
    "/{aid}/submissions/{sid}/manual/{item}",
    summary="Grade one staff-graded item of a submission (the course's staff)",
    responses={**ERRORS, **REFUSED},
)
def put_manual(aid: str, sid: str, item: str, body: ManualIn, request: Request, course: CourseDep,
               caller: CallerDep) -> dict:  # fmt: skip
    """The submission as the grading queue shows it, with this item's grade: the chosen levels' points summed
    and clamped to 0..the item's points (from the current spec), or `points`. 422 naming `item` for an unknown
    item, `rubric[i]` for an unknown level, `points` out of range."""
    a, who = _staff(course, aid, caller, request)
    return course.set_manual_grade(a, sid, item, body.model_dump(), who)


@router.get(
    "/{aid}/grading/next",
    summary="The next submission to grade (the course's staff), or 204",
    response_model=None,
    responses={204: {"description": "nothing left to grade"}, **REFUSED},
)
def grading_next(aid: str, request: Request, course: CourseDep, caller: CallerDep, grader: str | None = None,
                 after: str | None = None,
                 everyone: bool = Query(False, alias="all")) -> Response | dict:  # fmt: skip
    """Each roster student's counting submission without a grade of every manual item, in the roster's order
    (after `after`, wrapping): `{submission, student ({id, name}, or null while anonymous), label, kind, render,
    reference, scene, auto: {status, score, max_score, late, feedback}, items (the spec's), manual (the grades so
    far), remaining, url}`. When graders are assigned, the caller's own (or `grader`'s), or everyone's (`all`)."""
    a, who = _staff(course, aid, caller, request)
    out = course.next_to_grade(a, who, grader, after, everyone)
    return Response(status_code=204) if out is None else out


@router.get("/{aid}/grading", summary="The manual grading's state (the course's staff)", responses=REFUSED)
def grading_state(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """`{released, released_at, anonymous, max_points, staff: [{id, name, role}], graders: [{id, students}], you,
    items, remaining (the caller's queue), remaining_all (everyone's)}`."""
    a, who = _staff(course, aid, caller, request)
    out = course.grading_state(a, who)
    out["items"] = [m.model_dump() for m in course.manual_items(a)]
    out["remaining"] = len(course.queue(a, who)) if out["items"] else 0
    out["remaining_all"] = len(course.queue(a, who, everyone=True)) if out["items"] else 0
    return out


@router.get("/{aid}/grading/submissions/{sid}", summary="A submission as the grading queue shows it",
            responses=REFUSED)  # fmt: skip
def grading_submission(aid: str, sid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    a, who = _staff(course, aid, caller, request)
    return course.grading_view(a, _sub(course, a, sid), who)


@router.get("/{aid}/grading/submissions/{sid}/scene.json", summary="A scene submission as sent", responses=REFUSED)
def grading_scene(aid: str, sid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    a, _ = _staff(course, aid, caller, request)
    text = course.scene_text(a, _sub(course, a, sid))
    if text is None:
        raise ApiError(404, [{"path": "sid", "message": "an image submission has no scene"}])
    return Response(text, media_type="application/json", headers={"Cache-Control": "no-store"})


@router.post("/{aid}/grading/assign", summary="Deal the roster's submissions to graders evenly (an instructor)",
             responses={**ERRORS, **REFUSED})  # fmt: skip
def grading_assign(aid: str, body: GradersIn, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """`{graders: [{id, students}]}`: the roster's students dealt in turn, as many each within one; the queue
    of each then holds their own."""
    a, who = _staff(course, aid, caller, request, "release")
    return course.assign_graders(a, body.graders, who)


@router.put("/{aid}/grading/settings", summary="Anonymous grading on or off (an instructor)",
            responses={**ERRORS, **REFUSED})  # fmt: skip
def grading_settings(aid: str, body: GradingSettingsIn, request: Request, course: CourseDep,
                     caller: CallerDep) -> dict:  # fmt: skip
    a, who = _staff(course, aid, caller, request, "release")
    course.set_anonymous(a, body.anonymous, who)
    return course.grading_state(a, who)


@router.post("/{aid}/release", summary="Release the manual grades to the students, exports and LMS (an instructor)",
             responses=REFUSED)  # fmt: skip
def release(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """`{released: true, released_at, anonymous, max_points}`: from now on a grade is the auto part plus the
    manual part, in the student's view, grades.csv, the gradebook and the LMS (a later grade too)."""
    a, who = _staff(course, aid, caller, request, "release")
    return course.release(a, who)
