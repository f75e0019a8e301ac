"""An assignment's roster (docs/assignments.md): the roster uploaded (each student's link and token), read back
with each student's deadline, one student's link replaced, an extension, and joining an open assignment by a
name. The rules live in server/course/roster.py."""

from __future__ import annotations

import json

from fastapi import APIRouter, Request, Response
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from server.api.deps import (
    CallerDep,
    CapsDep,
    CourseDep,
    StoreDep,
    client_address,
    instructor_check,
)
from server.api.models import ErrorResponse
from server.api.routes.course_common import (
    ERRORS,
    NOT_FOUND,
    base_url,
    csv_response,
    roster_text,
    staff_assignment,
    staff_who,
)
from server.course.base import iso
from server.course.policy import Instant
from server.course.roster import links_csv

router = APIRouter(prefix="/api/assignments", tags=["assignments"])


class ExtensionIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    student: str = Field(min_length=1, max_length=80, description="the roster's id")
    deadline: Instant | None = Field(description="their own deadline (ISO 8601 with a zone); null: the assignment's")
    why: str = Field("", max_length=500, description="why (kept in the extension's history and the audit trail)")


class JoinIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str = Field(min_length=1, max_length=120, description="the name to be known by (self-declared)")


@router.post(
    "/{aid}/roster",
    summary="Upload the roster (text/csv: id,name,email)",
    responses={**ERRORS, **NOT_FOUND},
    openapi_extra={"requestBody": {"required": True, "content": {"text/csv": {"schema": {"type": "string"}}}}},
)
async def roster(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """200 with `students: [{id, name, email, link, token, new}]`: each new student's token is shown this once
    (kept hashed). `Accept: text/csv` answers the links as CSV (id,name,email,link) to mail out."""
    who = staff_who(course, aid, caller, request, "roster")
    text = await roster_text(request)
    students = await run_in_threadpool(course.roster, aid, text, base_url(request), who)
    if "text/csv" in request.headers.get("accept", ""):
        return csv_response(links_csv(students), "links.csv")
    return Response(
        json.dumps({"students": students}), media_type="application/json", headers={"Cache-Control": "no-store"}
    )


@router.get("/{aid}/roster", summary="The roster with each student's deadline (no tokens)", responses=NOT_FOUND)
def roster_list(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    a = staff_assignment(course, aid, caller, request)
    out = []
    for s in course.store.students(aid):
        due, cut = course.deadlines(a, s)
        out.append(
            {
                "id": s["student"],
                "name": s["name"],
                "email": s["email"],
                "self_declared": bool(s["self_declared"]),
                "deadline": iso(due),
                "extended": s["deadline"] is not None,
            }
        )
    return {"students": out}


@router.post(
    "/{aid}/students/{student}/link",
    summary="Replace one student's link (the old one stops working)",
    responses=NOT_FOUND,
)
def new_link(aid: str, student: str, request: Request, course: CourseDep, caller: CallerDep, store: StoreDep) -> dict:
    who = staff_who(course, aid, caller, request, "roster")
    return course.new_link(aid, student, base_url(request), store, who)


@router.post("/{aid}/extensions", summary="Move one student's deadline", responses={**ERRORS, **NOT_FOUND})
def extend(aid: str, body: ExtensionIn, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """Their deadline and late cut-off. Each extension is kept (at, who, before, after, why): `extensions` in
    GET /api/assignments/{aid}/students/{student}."""
    _, who = course.staff(aid, caller, instructor_check(request), "extend")
    return course.extend(aid, body.student, body.deadline, who, body.why)


@router.post(
    "/{aid}/join",
    summary="Join an open assignment by a name",
    responses={
        **ERRORS,
        **NOT_FOUND,
        429: {
            "model": ErrorResponse,
            "description": "too many new tokens for one address (TRACER_MAX_NEW_TOKENS_PER_ADDRESS)",
        },
    },
)
def join(aid: str, body: JoinIn, request: Request, course: CourseDep, caps: CapsDep) -> dict:
    """Open assignments only: anyone with the link gets a token (shown once), marked self-declared. It is a new
    token of the request's address, under TRACER_MAX_NEW_TOKENS_PER_ADDRESS and TRACER_MAX_JOINS_PER_ADDRESS
    (server/core/clients.py), counted only when the join succeeds; an assignment takes at most
    TRACER_MAX_JOINS_PER_ASSIGNMENT joined students (403 past it)."""
    host = client_address(request)
    with caps.new_token(host) as room, caps.join(host) as joining:
        joined = course.join(aid, body.name, base_url(request))
        room.keep()
        joining.keep()
    return joined
