"""The course's side of LTI (server/course/lms.py, docs/lti.md): the picker's choice, a course's roster read from
its LMS again, an LMS course linked to a course by the admin, and the grades sent back. The launch itself
(/lti/login, /lti/launch, /lti/jwks) is server/api/routes/lti.py."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, Request
from fastapi.responses import Response
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from server.api.answers import respond
from server.api.deps import CallerDep, CourseDep, LtiDep, get_lms, instructor_check, require_instructor
from server.api.errors import ApiError

router = APIRouter(tags=["lti"])


@router.post("/lti/pick", include_in_schema=False)
async def pick(
    request: Request, pick: Annotated[str, Form(max_length=64)], assignment: Annotated[str, Form(max_length=64)]
) -> Response:
    """The picker's form (a one-time secret and the assignment picked)."""
    lms = get_lms(request)
    return respond(await run_in_threadpool(lms.picked, pick, assignment, str(request.base_url)))


@router.post("/lti/claim", include_in_schema=False)
async def claim(
    request: Request, claim: Annotated[str, Form(max_length=64)], link: Annotated[str, Form(max_length=2048)]
) -> Response:
    """A learner's roster link, given once while launched (their email is a roster student's, on a platform whose
    emails do not identify people): the LMS user and the roster student linked."""
    lms = get_lms(request)
    return respond(await run_in_threadpool(lms.claimed, claim, link))


class ContextIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    platform: str = Field(min_length=1, max_length=64, description="the platform's id (python -m server.lti list)")
    context: str = Field(min_length=1, max_length=255, description="the LMS course's id (its context id)")
    title: str = Field("", max_length=200)


@router.post("/api/courses/{cid}/lms/contexts", status_code=201, summary="Link an LMS course to this course (admin)")
def link_context(
    cid: str, body: ContextIn, request: Request, course: CourseDep, caller: CallerDep, lti: LtiDep
) -> dict:
    """For an LMS course whose launches should open an existing course (the default one, say) rather than a new
    one made at its instructor's first launch."""
    require_instructor(caller, request)
    course.course(cid)
    lms = get_lms(request)
    if lti.store.platform(body.platform) is None:
        raise ApiError(422, [{"path": "platform", "message": f"no registered platform '{body.platform[:64]}'"}])
    lms.store.link_context(body.platform, body.context, cid, body.title, course.now())
    return {"course": cid, "platform": body.platform, "context": body.context}


@router.post("/api/courses/{cid}/lms/sync", summary="Read the course's roster from its LMS now (NRPS)")
async def sync(cid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    course.course_staff(cid, caller, instructor_check(request))
    lms = get_lms(request)
    try:
        return await run_in_threadpool(lms.sync, cid)
    except Exception as e:  # noqa: BLE001 (the LMS's own failure, named)
        raise ApiError(502, [{"path": "", "message": f"the LMS did not give the roster: {e}"}]) from None


@router.get("/api/assignments/{aid}/lms", summary="The grades sent back to the LMS: pending, sent, the last error")
def grades_back(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    a, _ = course.staff(aid, caller, instructor_check(request))
    return get_lms(request).board(aid, a["course_id"]) or {"contexts": [], "linked": False, "grades": None}


class SendAgainIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    score: int | None = Field(None, ge=1, description="one refused score's id (the dashboard's `refused`); all if none")


@router.post(
    "/api/assignments/{aid}/lms/send-again",
    summary="Queue the grades the LMS refused for good to be sent again (staff)",
)
def send_again(
    aid: str, request: Request, course: CourseDep, caller: CallerDep, body: SendAgainIn | None = None
) -> dict:
    """The assignment's scores the LMS refused (a 4xx other than 401 and 429: marked failed, not tried again) pending
    again, posted at once: after the LMS's side was fixed (the column re-opened, the student enrolled again)."""
    a, _ = course.staff(aid, caller, instructor_check(request))
    lms = get_lms(request)
    one = body.score if body is not None else None
    n = lms.poster.send_again(a["id"], one)
    if one is not None and n == 0:
        raise ApiError(404, [{"path": "score", "message": f"no refused score {one} of assignment {aid} to send again"}])
    return {"queued": n, "grades": lms.store.scores(a["id"])}
