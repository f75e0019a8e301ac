"""Courses (docs/assignments.md, "Courses and staff"): the server's admin creates a course and its staff; a
course's instructors enrol its roster once (one identity per student across the course's assignments) and
publish assignments into it; its TAs follow it. A student's token reads the course's page (their assignments).
The rules live in server/course/ (courses.py, roster.py) and server/course/people.py."""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Query, Request, Response
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from server.api.deps import CallerDep, CourseDep, StoreDep, instructor_check, require_instructor
from server.api.errors import ApiError
from server.api.models import ErrorResponse, Responses
from server.api.routes.assignments import ASSIGNMENT_BODY, publish_in
from server.api.routes.course_common import Why, base_url, roster_text
from server.core.roles import Kind, Role
from server.course.people import ROLES, Who
from server.course.roster import links_csv
from server.course.tokens import MAX_TOKENS, check_tokens

router = APIRouter(prefix="/api/courses", tags=["courses"])
ERRORS: Responses = {
    422: {"model": ErrorResponse, "description": "a field that is wrong, named with what was expected"}
}
NOT_FOUND: Responses = {404: {"model": ErrorResponse, "description": "no such course (or not yours)"}}


class CourseIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    id: str = Field(min_length=1, max_length=40, description="1 to 40 letters, digits, '-' or '_' (in its URLs)")
    name: str = Field("", max_length=200, description="its name, as students see it")
    late_tokens: int = Field(
        0, strict=True, description=f"late tokens (days) each student may spend (0 to {MAX_TOKENS})"
    )


class CourseEdit(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str | None = Field(None, max_length=200, description="its name, as students see it")
    late_tokens: int | None = Field(
        None, strict=True, description=f"late tokens (days) each student may spend (0 to {MAX_TOKENS})"
    )


class TokensIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    add: int = Field(strict=True, description=f"late tokens (days) to give the student (1 to {MAX_TOKENS})")
    why: str = Field("", max_length=500, description="why (kept with the grant)")


class StaffIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    id: str = Field(min_length=1, max_length=80, description="an id like a roster's (letters, digits, . _ -)")
    name: str = Field("", max_length=200)
    email: str = Field("", max_length=254)
    role: str = Field(description=f"one of {', '.join(ROLES)}")


@router.post("", status_code=201, summary="Create a course (the server admin's)", responses=ERRORS)
def create(body: CourseIn, request: Request, course: CourseDep, caller: CallerDep, response: Response) -> dict:
    require_instructor(caller, request)
    check_tokens(body.late_tokens)
    c = course.create_course(body.id, body.name)
    if body.late_tokens:
        course.set_late_tokens(c["id"], body.late_tokens, Who(None, Role.ADMIN))
    response.headers["Location"] = f"/api/courses/{c['id']}"
    return course.course_view(c["id"], Who(None, Role.ADMIN), base_url(request))


@router.get("", summary="The courses: every one (the admin), or the caller's own (staff, student)")
def listing(request: Request, course: CourseDep, caller: CallerDep) -> dict:
    mine = course.store.token(caller.owner) if caller.owner else None
    if mine is not None:
        cids = [mine["course_id"]]
    else:
        require_instructor(caller, request)
        cids = [c["id"] for c in course.store.courses()]
    out = []
    for cid in cids:
        c = course.store.course(cid)
        if c is None:  # (none: the ids are the courses')
            continue
        out.append(
            {"id": cid, "name": c["name"], "assignments": len(course.store.assignments(cid)),
             "students": len(course.store.members(cid)), "url": f"/api/courses/{cid}"}
        )  # fmt: skip
    return {"courses": out}


@router.get("/{cid}", summary="A course: its assignments (a student: their own), its staff", responses=NOT_FOUND)
def view(cid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    course.course(cid)
    who = course.role(cid, caller)
    if who is None:
        raise ApiError(404, [{"path": "course", "message": f"no course with id '{cid[:64]}'"}])
    return course.course_view(cid, who, base_url(request))


@router.patch("/{cid}", summary="Edit a course's settings (its instructors')", responses={**ERRORS, **NOT_FOUND})
def edit(cid: str, body: CourseEdit, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """`{name?, late_tokens?}`: what is given changes. `late_tokens` moves every student's tokens left by as
    much (what they spent stays spent)."""
    who = course.course_staff(cid, caller, instructor_check(request), "publish")
    if body.late_tokens is not None:
        course.set_late_tokens(cid, check_tokens(body.late_tokens), who)
    if body.name is not None:
        course.store.rename_course(cid, " ".join(body.name.split())[:200] or cid)
    return course.course_view(cid, who, base_url(request))


@router.get("/{cid}/students/{student}/tokens", summary="A student's late tokens and grants", responses=NOT_FOUND)
def tokens(cid: str, student: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    course.course_staff(cid, caller, instructor_check(request))
    _member(course, cid, student)
    return course.tokens_of(cid, student)


@router.post(
    "/{cid}/students/{student}/tokens",
    summary="Grant a student more late tokens (instructors and TAs)",
    responses={**ERRORS, **NOT_FOUND},
)
def grant_tokens(
    cid: str, student: str, body: TokensIn, request: Request, course: CourseDep, caller: CallerDep
) -> dict:
    """`{add, why}` -> the student's tokens (left, the course's, granted, spent, `grants`: each with at, who,
    add, before, after, why)."""
    who = course.course_staff(cid, caller, instructor_check(request), "extend")
    _member(course, cid, student)
    return course.grant_tokens(cid, student, body.add, body.why, who)


@router.post(
    "/{cid}/assignments",
    status_code=201,
    summary="Publish an assignment into this course (its instructors')",
    responses={**ERRORS, **NOT_FOUND},
    openapi_extra=ASSIGNMENT_BODY,
)
async def publish(cid: str, request: Request, course: CourseDep, caller: CallerDep, response: Response) -> dict:
    return await publish_in(request, course, caller, response, cid)


@router.post(
    "/{cid}/roster",
    summary="Enrol the course's roster once (text/csv: id,name,email): every assignment of the course",
    responses={**ERRORS, **NOT_FOUND},
    openapi_extra={"requestBody": {"required": True, "content": {"text/csv": {"schema": {"type": "string"}}}}},
)
async def roster(cid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """200 with `students: [{id, name, email, link, token, new}]`: each student's link opens the course's page
    (their assignments). `Accept: text/csv` answers the links as CSV to mail out."""
    who = course.course_staff(cid, caller, instructor_check(request), "roster")
    text = await roster_text(request)
    students = await run_in_threadpool(course.course_roster, cid, text, base_url(request), who)
    return _students(students, request)


@router.get("/{cid}/roster", summary="The course's roster (no tokens)", responses=NOT_FOUND)
def roster_list(cid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    course.course_staff(cid, caller, instructor_check(request))
    return {
        "students": [
            {"id": m["student"], "name": m["name"], "email": m["email"], "self_declared": bool(m["self_declared"]),
             "every_assignment": bool(m["every"]), "lms": m["lti_user"] is not None,
             "active": m["left_at"] is None, "left_at": m["left_at"]}
            for m in course.store.members(cid)
        ]
    }  # fmt: skip


# ?assignment= of the links routes
OneAssignment = Annotated[
    str | None, Query(description="only this assignment's roster, with links to its page (default: the course's)")
]


@router.get("/{cid}/links", summary="Every student's link again (the course's instructors')", responses=NOT_FOUND)
def links(
    cid: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    assignment: OneAssignment = None,
) -> Response:
    """The links are derived, not stored: the same ones as the roster gave, until a student's link is replaced.
    `Accept: text/csv` answers CSV (id,name,email,link)."""
    course.course_staff(cid, caller, instructor_check(request), "roster")
    _of_course(course, cid, assignment)
    return _students(course.links(cid, base_url(request), assignment), request)


@router.post(
    "/{cid}/links/renew", summary="A new link for every student (the old ones stop working)", responses=NOT_FOUND
)
def renew_links(
    cid: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    store: StoreDep,
    assignment: OneAssignment = None,
) -> Response:
    """Re-issue all at once: each student gets a new token (every earlier one stops working, in every assignment
    of the course; their workspace jobs move to it). The new links, as `GET /links` gives them (`Accept: text/csv`
    for CSV), `new` true."""
    who = course.course_staff(cid, caller, instructor_check(request), "roster")
    _of_course(course, cid, assignment)
    return _students(course.renew_links(cid, base_url(request), store, assignment, who), request)


@router.delete("/{cid}/students/{student}", summary="Take a student off the course's roster", responses=NOT_FOUND)
def remove_student(
    cid: str, student: str, request: Request, course: CourseDep, caller: CallerDep, why: Why = ""
) -> dict:
    """Their tokens stop working; their submissions and grades are kept (and read again if they are enrolled
    again)."""
    who = course.course_staff(cid, caller, instructor_check(request), "roster")
    course.remove_member(cid, student, who, why)
    return {"id": student, "removed": True}


@router.post("/{cid}/staff", status_code=201, summary="Add an instructor or a TA (shown their link)", responses=ERRORS)
def add_staff(cid: str, body: StaffIn, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """The server admin or the course's instructors: `{id, name, email, role}` -> their token and link (the
    /course page with the token), never cached."""
    who = course.course_staff(cid, caller, instructor_check(request), "staff")
    out = course.add_staff(cid, body.id, body.name, body.email, body.role, base_url(request), who)
    headers = {"Cache-Control": "no-store"}
    return Response(json.dumps(out), status_code=201, media_type="application/json", headers=headers)


@router.get("/{cid}/staff", summary="The course's staff (no tokens)", responses=NOT_FOUND)
def staff(cid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    course.course_staff(cid, caller, instructor_check(request))
    return {"staff": course.course_view(cid, Who(), base_url(request))["staff"]}


@router.post("/{cid}/staff/{person}/link", summary="A staff member's link: the same, or new (?renew=true)")
def staff_link(
    cid: str,
    person: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    store: StoreDep,
    renew: Annotated[bool, Query(description="a new token: the old one stops working")] = False,
) -> Response:
    who = course.course_staff(cid, caller, instructor_check(request), "staff")
    if renew and course.store.staff_member(cid, person) is not None:
        course.renew(cid, Kind.STAFF, person, store, who, "a new staff link")
    out = course.staff_link(cid, person, base_url(request))
    return Response(json.dumps(out), media_type="application/json", headers={"Cache-Control": "no-store"})


@router.delete("/{cid}/staff/{person}", summary="Remove a staff member (their token stops working)")
def remove_staff(cid: str, person: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    who = course.course_staff(cid, caller, instructor_check(request), "staff")
    course.remove_staff(cid, person, who)
    return {"id": person, "removed": True}


def _member(course, cid: str, student: str) -> None:
    if course.store.member(cid, student) is None:
        raise ApiError(404, [{"path": "student", "message": f"no student '{student[:80]}' in course '{cid}'"}])


def _of_course(course, cid: str, assignment: str | None) -> None:
    """A 404 unless `assignment` (when given) is one of the course's."""
    if assignment is not None and course.assignment(assignment)["course_id"] != cid:
        raise ApiError(404, [{"path": "assignment", "message": f"no assignment '{assignment[:64]}' in course '{cid}'"}])


def _students(students: list[dict], request: Request) -> Response:
    if "text/csv" in request.headers.get("accept", ""):
        headers = {"Content-Disposition": 'attachment; filename="links.csv"', "Cache-Control": "no-store"}
        return Response(links_csv(students), media_type="text/csv", headers=headers)
    return Response(
        json.dumps({"students": students}), media_type="application/json", headers={"Cache-Control": "no-store"}
    )
