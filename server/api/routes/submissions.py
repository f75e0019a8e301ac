"""Submissions (docs/assignments.md): a student submits a scene or an image, or checks one without submitting;
their submissions (all of them to staff), one as its grade moves (Server-Sent Events), its pictures, its ray trees
beside the reference's, and Gradescope's results.json. A student sees only their own. The rules live in
server/course/submissions.py and views.py."""

from __future__ import annotations

import base64
import binascii
import json
import time
from collections.abc import AsyncGenerator
from typing import Annotated

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

from server.api.deps import (
    CallerDep,
    CapsDep,
    ChecksDep,
    CourseDep,
    JobsDep,
    SettingsDep,
    StoppingDep,
    TreeCacheDep,
)
from server.api.errors import ApiError
from server.api.models import CheckIn, ErrorResponse, HandedIn
from server.api.routes.course_common import ERRORS, NOT_FOUND, staff_assignment
from server.api.streams import KEEP_ALIVE, event_stream, sse
from server.course import compare, owntrees
from server.jobs.service import KEEPALIVE

router = APIRouter(prefix="/api/assignments", tags=["assignments"])


SubmissionIn = HandedIn  # POST /api/assignments/{id}/submissions and /check


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
    if not who.instructor and caller.owner is not None:  # (a student's: their token's hash)
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
    subs = course.submissions(a, None if who.student is None else who.student["student"])
    counting: dict[str, str] = {}
    for student in {s["student"] for s in subs}:
        c = course.counting(a, [s for s in subs if s["student"] == student])
        if c is not None:
            counting[student] = c["id"]
    views = [course.view(a, s, who, counting.get(s["student"])) for s in subs]
    if course.hides_names(a, who):  # anonymous grading: a TA sees the queue's labels (server/course/manual.py)
        labels = course.anonymous_labels(a)
        views = [{**v, "student": labels.get(v["student"], "Student ?")} for v in views]
    return {"submissions": views}


@router.get("/{aid}/submissions/{sid}", summary="One submission: status, score, feedback", responses=NOT_FOUND)
def submission(aid: str, sid: str, course: CourseDep, caller: CallerDep) -> dict:
    a, who = course.who(aid, caller)
    sub = course.submission(a, sid)
    if sub is None or not (who.student is None or sub["student"] == who.student["student"]):
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
    return course.view_one(a, sub, who)


FINAL = ("graded", "invalid", "failed")
INT32 = 2**31 - 1  # a query's number is checked against the image when the submission is read; this bound comes


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
    if sub is None or not (who.student is None or sub["student"] == who.student["student"]):
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])

    async def events() -> AsyncGenerator[str, None]:
        last, quiet = None, time.monotonic()
        with course.follow(sid) as follower:
            while True:
                view = await run_in_threadpool(lambda: course.view_one(a, course.submission(a, sid) or sub, who))
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
    a = staff_assignment(course, aid, caller, request)
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
    if sub is None or not (who.student is None or sub["student"] == who.student["student"]):
        raise ApiError(404, [{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
    path = course.file(a, sub, who, name)
    if path is None:
        raise ApiError(404, [{"path": "name", "message": f"no {name[:40]!r} to show for this submission"}])
    return Response(path.read_bytes(), media_type="image/png", headers={"Cache-Control": "no-store"})
