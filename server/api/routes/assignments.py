"""Assignments (the course, docs/assignments.md): the instructor publishes a grading spec with a deadline and
a policy, uploads the roster and reads the grades; a student opens the brief with their link's token,
submits scenes or images and reads their own submissions. A student sees only their own work: every other
answer is the 404 of an unknown id. The rules live in server/course/service.py."""

from __future__ import annotations

import base64
import binascii
import json
import time
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import StreamingResponse
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from starlette.concurrency import run_in_threadpool

from server.api.deps import (
    CallerDep,
    CapsDep,
    ChecksDep,
    CourseDep,
    JobsDep,
    MaybeLmsDep,
    SettingsDep,
    StoppingDep,
    StoreDep,
    TreeCacheDep,
    client_address,
    instructor_check,
    require_instructor,
)
from server.api.errors import ApiError
from server.api.models import CheckIn, ErrorResponse, HandedIn
from server.api.streams import KEEP_ALIVE, event_stream, sse
from server.core.security import Caller
from server.course import compare, owntrees
from server.course import dashboard as course_board
from server.course.base import iso
from server.course.people import Who
from server.course.policy import AssignmentIn, Instant
from server.course.roster import links_csv
from server.course.service import Course
from server.course.store import DEFAULT_COURSE
from tracer.errors import pydantic_errors

router = APIRouter(prefix="/api/assignments", tags=["assignments"])
ERRORS = {422: {"model": ErrorResponse, "description": "a field that is wrong, named with what was expected"}}
NOT_FOUND = {404: {"model": ErrorResponse, "description": "no such assignment (or not yours)"}}


SubmissionIn = HandedIn  # POST /api/assignments/{id}/submissions and /check


class ExtensionIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    student: str = Field(min_length=1, max_length=80, description="the roster's id")
    deadline: Instant | None = Field(description="their own deadline (ISO 8601 with a zone); null: the assignment's")


class JoinIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str = Field(min_length=1, max_length=120, description="the name to be known by (self-declared)")


def _base(request: Request) -> str:
    return str(request.base_url)


def _instructor(course: Course, aid: str, caller: Caller, request: Request, action: str = "follow") -> dict:
    """The assignment, for its course's staff only (a TA for what a TA may do, else 403): its students' tokens
    get the 404 of an unknown id (on a server where everyone is the instructor too), anyone else 401 or 403."""
    return course.staff(aid, caller, instructor_check(request), action)[0]


async def _assignment_body(request: Request) -> AssignmentIn:
    """JSON, or multipart (spec and reference as files or fields, the policy as fields; feedback and starter
    as JSON text), as the repository's scenes/grading/ has it."""
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind == "multipart/form-data":
        form = await request.form()
        data: dict[str, Any] = {}
        for key, value in form.multi_items():
            text = (await value.read()).decode("utf-8", errors="replace") if hasattr(value, "read") else value
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


async def publish_in(request: Request, course: Course, caller: Caller, response: Response, cid: str | None) -> dict:
    named = cid is not None  # (a course the caller did not name is not hidden from them: course_staff)
    if cid is None:
        mine = course.store.token(caller.owner) if caller.owner else None
        cid = mine["course_id"] if mine is not None and mine["kind"] == "staff" else DEFAULT_COURSE
    course.course_staff(cid, caller, instructor_check(request), "publish", hide=named)
    body = await _assignment_body(request)
    a = await run_in_threadpool(course.publish, body, cid)
    response.headers["Location"] = f"/api/assignments/{a['id']}"
    return course.brief(a, Who(), _base(request))


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
) -> dict:
    _instructor(course, aid, caller, request, "publish")
    body = await _assignment_body(request)
    a = await run_in_threadpool(course.edit, aid, body, regrade)
    return course.brief(a, Who(), _base(request))


@router.post(
    "/{aid}/regrade",
    summary="Grade every submission again (a new version, the same spec and policy)",
    responses=NOT_FOUND,
)
def regrade(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """For a course's instructors and TAs: after a grading fix, or a doubt; the earlier grades stay in their
    version's run."""
    _instructor(course, aid, caller, request, "regrade")
    return course.brief(course.regrade(aid), Who(), _base(request))


@router.get("", summary="Every assignment (the admin's), or a course's (its staff's)")
def listing(
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    course_id: Annotated[str | None, Query(alias="course", description="only this course's")] = None,
) -> dict:
    mine = course.store.token(caller.owner) if caller.owner else None
    if mine is not None and mine["kind"] == "staff" and course_id in (None, mine["course_id"]):
        course_id = mine["course_id"]
        course.course_staff(course_id, caller, instructor_check(request))
    else:
        require_instructor(caller, request)
    out = []
    for aid in course.store.assignments(course_id):
        a = course.store.assignment(aid)
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
    return course.brief(a, who, _base(request))


@router.post(
    "/{aid}/roster",
    summary="Upload the roster (text/csv: id,name,email)",
    responses={**ERRORS, **NOT_FOUND},
    openapi_extra={"requestBody": {"required": True, "content": {"text/csv": {"schema": {"type": "string"}}}}},
)
async def roster(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """200 with `students: [{id, name, email, link, token, new}]`: each new student's token is shown this once
    (kept hashed). `Accept: text/csv` answers the links as CSV (id,name,email,link) to mail out."""
    _instructor(course, aid, caller, request, "roster")
    text = await roster_text(request)
    students = await run_in_threadpool(course.roster, aid, text, _base(request))
    if "text/csv" in request.headers.get("accept", ""):
        return _csv(links_csv(students), "links.csv")
    return Response(
        json.dumps({"students": students}), media_type="application/json", headers={"Cache-Control": "no-store"}
    )


@router.get("/{aid}/roster", summary="The roster with each student's deadline (no tokens)", responses=NOT_FOUND)
def roster_list(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    a = _instructor(course, aid, caller, request)
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
    _instructor(course, aid, caller, request, "roster")
    return course.new_link(aid, student, _base(request), store)


@router.post("/{aid}/extensions", summary="Move one student's deadline", responses={**ERRORS, **NOT_FOUND})
def extend(aid: str, body: ExtensionIn, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    _instructor(course, aid, caller, request, "extend")
    return course.extend(aid, body.student, body.deadline)


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
        joined = course.join(aid, body.name, _base(request))
        room.keep()
        joining.keep()
    return joined


@router.post(
    "/{aid}/submissions",
    status_code=202,
    summary="Submit a scene or an image (a student's)",
    responses={
        **ERRORS,
        **NOT_FOUND,
        403: {"model": ErrorResponse, "description": "past the cut-off, or no attempts left"},
        429: {"model": ErrorResponse, "description": "past TRACER_MAX_SUBMISSIONS_PER_HOUR"},
    },
)
def submit(
    aid: str, body: SubmissionIn, request: Request, course: CourseDep, caller: CallerDep, response: Response
) -> dict:
    """202 with `id` and `status` (queued): kept at once, with the API's clock time when its body was
    accepted, then graded once in the batch lane."""
    accepted = course.now()  # the body was read and parsed before this runs
    a, who = course.who(aid, caller)
    kind, data = _submitted(body)
    sub = course.submit(a, who, kind, data, accepted)
    response.headers["Location"] = f"/api/assignments/{aid}/submissions/{sub['id']}"
    return course.view(a, sub, who)


@router.post(
    "/{aid}/check",
    summary="Check a scene or an image as the policy shows it now (no attempt)",
    responses={
        **ERRORS,
        **NOT_FOUND,
        429: {"model": ErrorResponse, "description": "past TRACER_MAX_CHECKS_PER_MINUTE"},
    },
)
async def check(
    aid: str, body: CheckIn, request: Request, course: CourseDep, caller: CallerDep, caps: CapsDep, jobs: JobsDep,
    checks: ChecksDep, settings: SettingsDep, cache: TreeCacheDep,
) -> dict:  # fmt: skip
    """The body of a submission -> `valid`, `tests` (validity and the requirements, each as the feedback
    policy shows it now), `errors` at their JSON paths, `warnings`, and the `image_tests` a submission would
    also get. Nothing is kept and no attempt is used; it runs in seconds (no render). A student's token checks
    at most TRACER_MAX_CHECKS_PER_MINUTE times a minute (429 past it). With an image, `trees` (a tree log of
    your own tracer, docs/own-tracer.md) gives `trees`: each compared with the reference's, when the policy
    shows the error map now."""
    a, who = await run_in_threadpool(course.who, aid, caller)
    if not who.instructor:
        caps.check(caller.owner)
    kind, data = _submitted(body)
    if body.trees is not None and kind == "scene":
        raise ApiError(422, [{"path": "trees", "message": "a tree log goes with an image from your own tracer, "
                              "not with a scene (the service traces a scene's trees itself)"}])  # fmt: skip
    out = await run_in_threadpool(course.check, a, who, kind, data)
    if body.trees is not None:
        await run_in_threadpool(compare.allowed, course, a, {"version": a["version"]}, who)
        out["trees"] = await owntrees.check_log(
            course, jobs, lambda b: checks.summary(request.is_disconnected, b), cache, a,
            who, body.trees, settings.max_tree_log_trees, request.is_disconnected,
        )  # fmt: skip
    return out


def _submitted(body: SubmissionIn) -> tuple[str, bytes]:
    if body.image is not None:
        try:
            return body.format, base64.b64decode(body.image, validate=True)
        except (binascii.Error, ValueError):
            raise ApiError(422, [{"path": "image", "message": "expected base64 data"}]) from None
    return "scene", (body.scene if isinstance(body.scene, str) else json.dumps(body.scene)).encode()


@router.get("/{aid}/submissions", summary="Submissions: a student's own, or all (the instructor)", responses=NOT_FOUND)
def submissions(aid: str, course: CourseDep, caller: CallerDep) -> dict:
    a, who = course.who(aid, caller)
    subs = course.submissions(a, None if who.instructor else who.student["student"])
    counting: dict[str, str] = {}
    for student in {s["student"] for s in subs}:
        c = course.counting(a, [s for s in subs if s["student"] == student])
        if c is not None:
            counting[student] = c["id"]
    return {"submissions": [course.view(a, s, who, counting.get(s["student"])) for s in subs]}


@router.get("/{aid}/submissions/{sid}", summary="One submission: status, score, feedback", responses=NOT_FOUND)
def submission(aid: str, sid: str, course: CourseDep, caller: CallerDep) -> dict:
    a, who = course.who(aid, caller)
    sub = course.submission(a, sid)
    if sub is None or not (who.instructor or sub["student"] == who.student["student"]):
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
    return course.view_one(a, sub, who)


FINAL = ("graded", "invalid", "failed")
INT32 = 2**31 - 1  # a query's number is checked against the image when the submission is read; this bound comes
# first, so that a huge one is an error at its own name even beside a missing other one
KEEPALIVE = 15.0  # seconds of quiet after which a comment keeps the stream open


@router.get(
    "/{aid}/submissions/{sid}/events",
    summary="Server-Sent Events: the submission as its grade moves",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}, **NOT_FOUND},
)
async def submission_events(
    aid: str, sid: str, request: Request, course: CourseDep, caller: CallerDep, stopping: StoppingDep
):
    """`submission` {the submission as GET .../submissions/{sid} shows it} now and each time its grade moves
    (queued, grading, then graded, invalid or failed), then `end`, and the stream closes. Woken by the
    grading run when the submission's row changes: it never polls the store."""
    a, who = await run_in_threadpool(course.who, aid, caller)
    sub = await run_in_threadpool(course.submission, a, sid)
    if sub is None or not (who.instructor or sub["student"] == who.student["student"]):
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])

    async def events() -> AsyncIterator[str]:
        last, quiet = None, time.monotonic()
        with course.follow(sid) as follower:
            while True:
                view = await run_in_threadpool(lambda: course.view_one(a, course.submission(a, sid), who))
                if view != last:
                    last = view
                    yield sse("submission", view)
                if view["status"] in FINAL:
                    yield sse("end", {})
                    return
                while await follower.changed(1.0) is None:
                    if stopping():  # a client that left: the response cancels this (server/api/routes/jobs.py)
                        return
                    if time.monotonic() - quiet > KEEPALIVE:
                        quiet = time.monotonic()
                        yield KEEP_ALIVE

    return event_stream(request, caller, events())  # 429 past the caller's open streams (server/core/clients.py)


@router.get(
    "/{aid}/submissions/{sid}/results.json",
    summary="A graded submission as Gradescope's autograder results.json",
    responses=NOT_FOUND,
)
def gradescope_results(aid: str, sid: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """For a Gradescope autograder that hands the student's work to this service: the tests with their
    scores, each test's visibility from the feedback policy, the score after the late penalty. The
    instructor's (its token is the autograder's)."""
    a = _instructor(course, aid, caller, request)
    sub = course.submission(a, sid)
    results = course.gradescope(a, sub) if sub is not None else None
    if results is None:
        raise ApiError(404, [{"path": "sid", "message": f"no graded submission with id '{sid[:64]}'"}])
    return results


@router.get(
    "/{aid}/submissions/{sid}/raytree",
    summary="A pixel's ray trees: the student's scene beside the reference's, and where they first differ",
    responses={
        **ERRORS,
        **NOT_FOUND,
        403: {"model": ErrorResponse, "description": "the feedback policy does not show the reference's structure yet"},
        409: {"model": ErrorResponse, "description": "an image submission (no scene), or not graded (yet)"},
        503: {"model": ErrorResponse, "description": "no worker takes interactive work"},
        504: {"model": ErrorResponse, "description": "a tree took longer than TRACER_MAX_RAYTREE_SECONDS"},
    },
)
async def submission_raytree(
    aid: str,
    sid: str,
    request: Request,
    course: CourseDep,
    caller: CallerDep,
    jobs: JobsDep,
    checks: ChecksDep,
    x: Annotated[int, Query(ge=-INT32, le=INT32, description="a column of the graded image (render.png)")],
    y: Annotated[int, Query(ge=-INT32, le=INT32, description="a row of the graded image, from the top")],
    sample: Annotated[int, Query(ge=-INT32, le=INT32, description="the sample index within the pixel")] = 0,
) -> dict:
    """`{x, y, sample, student, reference, difference}`: both ray trees of that pixel sample (the format of POST
    /api/raytree), traced by workers as the grader rendered the scenes (server/course/compare.py), and the first
    node where they differ, `{student: path, reference: path, what, message, nodes}` (a path: child indices from
    the eye ray), or null. Shown when the image tests' pictures are (the feedback policy); the instructor's always."""
    return await compare.raytrees(
        course, jobs, lambda body: checks.summary(request.is_disconnected, body), caller, aid, sid,
        x, y, sample, request.is_disconnected,
    )  # fmt: skip


@router.get("/{aid}/submissions/{sid}/{name}", summary="A graded submission's picture", responses=NOT_FOUND)
def submission_file(aid: str, sid: str, name: str, course: CourseDep, caller: CallerDep) -> Response:
    """render.png (always, once graded); error_map.png and rejected.png when no image test's feedback is
    hidden; reference.png when the policy shows the reference. The submission's `files` lists them."""
    a, who = course.who(aid, caller)
    sub = course.submission(a, sid)
    if sub is None or not (who.instructor or sub["student"] == who.student["student"]):
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
    path = course.file(a, sub, who, name)
    if path is None:
        raise ApiError(404, [{"path": "name", "message": f"no {name[:40]!r} to show for this submission"}])
    return Response(path.read_bytes(), media_type="image/png", headers={"Cache-Control": "no-store"})


@router.get("/{aid}/grades.csv", summary="The grades: one row per roster student", responses=NOT_FOUND)
def grades(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    return _csv(course.grades_csv(_instructor(course, aid, caller, request)), "grades.csv")


@router.get("/{aid}/gradebook.csv", summary="The grades as an LMS gradebook imports them", responses=NOT_FOUND)
def gradebook(aid: str, request: Request, course: CourseDep, caller: CallerDep) -> Response:
    """Canvas's gradebook columns (Student, ID, SIS User ID, SIS Login ID, Section, the assignment) and a
    Points Possible row: the roster's id is the SIS User ID, its email the SIS Login ID."""
    return _csv(course.gradebook_csv(_instructor(course, aid, caller, request)), "gradebook.csv")


async def roster_text(request: Request) -> str:
    """A roster upload's body as text (422 unless it is UTF-8)."""
    try:
        return (await request.body()).decode("utf-8")
    except UnicodeDecodeError:
        raise ApiError(422, [{"path": "", "message": "the roster must be UTF-8 text (CSV)"}]) from None


def _csv(text: str, filename: str) -> Response:
    """A CSV export, downloaded as `filename` and never cached (links carry tokens, grades are private)."""
    headers = {"Content-Disposition": f'attachment; filename="{filename}"', "Cache-Control": "no-store"}
    return Response(text, media_type="text/csv", headers=headers)


@router.get("/{aid}/reference.png", summary="The reference image (when the policy shows it)", responses=NOT_FOUND)
def reference_png(aid: str, course: CourseDep, caller: CallerDep) -> Response:
    a, who = course.who(aid, caller)
    path = course.reference_png(a) if who.instructor or a["policy"]["show_reference"] else None
    if path is None:
        raise ApiError(404, [{"path": "", "message": "no reference image (not shown, or not rendered yet)"}])
    return Response(path.read_bytes(), media_type="image/png", headers={"Cache-Control": "no-store"})


# -- the instructor's dashboard (web/course.html; server/course/dashboard.py)


@router.get(
    "/{aid}/dashboard", summary="The roster with each student's state and score (the instructor's)", responses=NOT_FOUND
)
def dashboard(aid: str, request: Request, course: CourseDep, caller: CallerDep, lms: MaybeLmsDep) -> dict:
    """Every roster student with their deadline (an extension marked), state (none, submitted, graded,
    invalid, failed), counting score, submissions and whether self-declared; and the class's counts, mean and
    median. One answer for the whole class, for a page that follows it while it submits."""
    a = _instructor(course, aid, caller, request)
    out = course_board.dashboard(course, a)
    out["tree_whats"] = owntrees.whats(course, a)  # own tracers: the class's first differences by `what`
    out["lms"] = lms.board(aid, a["course_id"]) if lms is not None else None
    out["course"] = a["course_id"]
    return out


@router.get(
    "/{aid}/students/{student}",
    summary="One student: their state and every submission (the instructor's)",
    responses=NOT_FOUND,
)
def student_detail(aid: str, student: str, request: Request, course: CourseDep, caller: CallerDep) -> dict:
    """The student's dashboard row and their history: each submission as GET .../submissions/{sid} shows it
    to the instructor (status, late, score, feedback, pictures), oldest first."""
    out = course_board.student_detail(course, _instructor(course, aid, caller, request), student)
    if out is None:
        raise ApiError(404, [{"path": "student", "message": f"no student '{student[:80]}' on the roster"}])
    return out
