"""Assignments (the course, docs/assignments.md): the instructor publishes a grading spec with a deadline and
a policy, edits it (a new version) or regrades; the list of a course's assignments; the brief (a student's, with
their link's token) and the reference image. A student sees only their own work: every other answer is the 404 of
an unknown id. The rules live in server/course/ (assignments.py). The roster, submissions and the dashboard are
routers of their own (roster.py, submissions.py, dashboard.py), under the same prefix."""

from __future__ import annotations

import json
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile

from server.api.deps import (
    CallerDep,
    CourseDep,
    instructor_check,
    require_instructor,
)
from server.api.errors import ApiError
from server.api.routes.course_common import ERRORS, NOT_FOUND, Why, base_url, staff_who
from server.core.roles import Kind
from server.core.security import Caller
from server.course.people import Who
from server.course.policy import AssignmentIn
from server.course.service import Course
from server.course.store import DEFAULT_COURSE
from tracer.errors import pydantic_errors

router = APIRouter(prefix="/api/assignments", tags=["assignments"])


async def _assignment_body(request: Request) -> AssignmentIn:
    """JSON, or multipart (spec and reference as files or fields, the policy as fields; feedback and starter
    as JSON text), as the repository's scenes/grading/ has it."""
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind == "multipart/form-data":
        form = await request.form()
        data: dict[str, Any] = {}
        for key, value in form.multi_items():
            text = (await value.read()).decode("utf-8", errors="replace") if isinstance(value, UploadFile) else value
            if key in ("spec", "reference", "starter", "feedback"):
                try:
                    data[key] = json.loads(text)
                except json.JSONDecodeError as e:
                    message = f"invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}"
                    raise ApiError(422, [{"path": key, "message": message}]) from None
            else:
                data[key] = text if text != "" else None
    elif kind in ("application/json", ""):
        try:
            data = json.loads(await request.body())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ApiError(422, [{"path": "", "message": f"the body is not JSON: {e}"}]) from None
    else:
        raise ApiError(415, [{"path": "", "message": "expected application/json or multipart/form-data"}])
    if not isinstance(data, dict):
        raise ApiError(422, [{"path": "", "message": "the body must be a JSON object"}])
    try:
        return AssignmentIn.model_validate(data)
    except ValidationError as e:
        raise ApiError(422, pydantic_errors(e, AssignmentIn)) from None


POLICY_FIELDS = {name: {"description": f.description or ""} for name, f in AssignmentIn.model_fields.items()}

REQUIRED = ["spec", "deadline"]

ASSIGNMENT_BODY = {  # for /docs: the route reads JSON or multipart itself (docs/assignments.md has every field)
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": {"type": "object", "required": REQUIRED, "properties": POLICY_FIELDS}},
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": REQUIRED,
                    "properties": {
                        **POLICY_FIELDS,
                        "spec": {"type": "string", "format": "binary", "description": "the spec's JSON file"},
                        "reference": {
                            "type": "string",
                            "format": "binary",
                            "description": "the reference scene's JSON file",
                        },
                    },
                }
            },
        },
    },
}


@router.post(
    "",
    status_code=201,
    summary="Publish an assignment (a course's instructor's)",
    responses=ERRORS,
    openapi_extra=ASSIGNMENT_BODY,
)
async def publish(
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    response: Response,
    course_id: Annotated[
        str | None,
        Query(alias="course", description="the course (default: the staff token's own course, else 'default')"),
    ] = None,
) -> dict:
    """`{"spec": {...}, "deadline": "...", ...policy}` -> 201 with `id`. The spec's reference scene inline, or
    as a file name with the scene beside it (`reference`). Its reference renders start now."""
    return await publish_in(request, course, caller, response, course_id)


def _publisher(request: Request, course: Course, caller: Caller, cid: str | None) -> tuple[str, Who]:
    """The course to publish in (named, else the staff token's own, else the default), once the caller may, and
    the caller."""
    named = cid is not None  # (a course the caller did not name is not hidden from them: course_staff)
    if cid is None:
        mine = course.store.token(caller.owner) if caller.owner else None
        cid = mine["course_id"] if mine is not None and mine["kind"] == Kind.STAFF else DEFAULT_COURSE
    who = course.course_staff(cid, caller, instructor_check(request), "publish", hide=named)
    return cid, who


async def publish_in(request: Request, course: Course, caller: Caller, response: Response, cid: str | None) -> dict:
    cid, who = _publisher(request, course, caller, cid)
    body = await _assignment_body(request)
    a = await run_in_threadpool(course.publish, body, cid, who)
    response.headers["Location"] = f"/api/assignments/{a['id']}"
    return course.brief(a, Who(), base_url(request))


@router.post(
    "/preview-feedback",
    summary="What a student will see under a policy, before publishing (nothing is kept)",
    responses=ERRORS,
    openapi_extra=ASSIGNMENT_BODY,
)
async def preview_feedback(
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    course_id: Annotated[str | None, Query(alias="course", description="the course it would be published in")] = None,
) -> dict:
    """The body of a publish (JSON or multipart, checked the same: 422 at its fields) -> the feedback of an
    example scene submission as a student would see it until the deadline (`moments[0]`) and after it
    (`moments[1]`), through the same rule as every submission's: each test shown or `hidden` with when, the
    pictures shown, and `withheld` (what is hidden and when it appears). Nothing is published or rendered."""
    _publisher(request, course, caller, course_id)
    body = await _assignment_body(request)
    return await run_in_threadpool(course.preview, body)


@router.put(
    "/{aid}",
    summary="Edit an assignment: a new version, the earlier kept",
    responses={**ERRORS, **NOT_FOUND},
    openapi_extra=ASSIGNMENT_BODY,
)
async def edit(
    aid: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    regrade: Annotated[bool, Query(description="grade every submission again under it")] = False,
    why: Why = "",
) -> dict:
    who = staff_who(course, aid, caller, request, "publish")
    body = await _assignment_body(request)
    a = await run_in_threadpool(course.edit, aid, body, regrade, who, why)
    return course.brief(a, Who(), base_url(request))


@router.post(
    "/{aid}/regrade",
    summary="Grade every submission again (a new version, the same spec and policy)",
    responses=NOT_FOUND,
)
def regrade(aid: str, request: Request, course: CourseDep, caller: CallerDep, why: Why = "") -> dict:
    """For a course's instructors and TAs: after a grading fix, or a doubt; the earlier grades stay in their
    version's run."""
    who = staff_who(course, aid, caller, request, "regrade")
    return course.brief(course.regrade(aid, who, why), Who(), base_url(request))


@router.get("", summary="Every assignment (the admin's), or a course's (its staff's)")
def listing(
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    course_id: Annotated[str | None, Query(alias="course", description="only this course's")] = None,
) -> dict:
    mine = course.store.token(caller.owner) if caller.owner else None
    if mine is not None and mine["kind"] == Kind.STAFF and course_id in (None, mine["course_id"]):
        course_id = mine["course_id"]
        course.course_staff(mine["course_id"], caller, instructor_check(request))
    else:
        require_instructor(caller, request)
    out = []
    for aid in course.store.assignments(course_id):
        a = course.store.assignment(aid)
        if a is None:  # (none: the course's ids are its assignments')
            continue
        out.append(
            {
                "id": aid,
                "course": a["course_id"],
                "name": a["spec"]["name"],
                "version": a["version"],
                "deadline": a["policy"]["deadline"],
                "students": len(course.store.students(aid)),
                "url": f"/api/assignments/{aid}",
            }
        )
    return {"assignments": out}


@router.get("/{aid}", summary="The brief (a student's) or everything (the instructor's)", responses=NOT_FOUND)
def brief(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    a, who = course.who(aid, caller)
    return course.brief(a, who, base_url(request))


@router.get("/{aid}/reference.png", summary="The reference image (when the policy shows it)", responses=NOT_FOUND)
def reference_png(aid: str, course: CourseDep, caller: CallerDep) -> Response:
    a, who = course.who(aid, caller)
    path = course.reference_png(a) if who.instructor or a["policy"]["show_reference"] else None
    if path is None:
        raise ApiError(404, [{"path": "", "message": "no reference image (not shown, or not rendered yet)"}])
    return Response(path.read_bytes(), media_type="image/png", headers={"Cache-Control": "no-store"})
