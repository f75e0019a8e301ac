"""A student's own tracer's tree log, compared with the reference's trees (server/course/owntrees.py,
docs/own-tracer.md): POST /api/assignments/{aid}/submissions/{sid}/trees."""

from __future__ import annotations

import re

from fastapi import APIRouter, Request

from server.api.deps import CallerDep, ChecksDep, CourseDep, JobsDep, SettingsDep
from server.api.models import ErrorResponse
from server.course import owntrees

router = APIRouter(prefix="/api/assignments", tags=["assignments"])
TREES_PATH = re.compile(r"/api/assignments/[^/]+/submissions/[^/]+/trees")  # its body limit (server/main.py)


def tree_cache(request: Request) -> owntrees.TreeCache:
    """The app's cache of the reference's trees (made on first use)."""
    state = request.app.state
    if getattr(state, "tree_cache", None) is None:
        state.tree_cache = owntrees.TreeCache()
    return state.tree_cache


@router.post(
    "/{aid}/submissions/{sid}/trees",
    summary="Your own tracer's ray trees at some pixels, compared with the reference's (docs/own-tracer.md)",
    responses={
        403: {"model": ErrorResponse, "description": "the feedback policy does not show the error map yet"},
        404: {"model": ErrorResponse, "description": "no such assignment or submission (or not yours)"},
        409: {"model": ErrorResponse, "description": "a scene submission, or an assignment without a reference"},
        413: {"model": ErrorResponse, "description": "a log past TRACER_MAX_TREE_LOG_BYTES"},
        422: {"model": ErrorResponse, "description": "a log with errors, each at its JSON path"},
        503: {"model": ErrorResponse, "description": "no worker takes interactive work"},
    },
)
async def trees(
    aid: str, sid: str, request: Request, course: CourseDep, caller: CallerDep, jobs: JobsDep, checks: ChecksDep,
    settings: SettingsDep,
) -> dict:  # fmt: skip
    """The body is the tree log, `{"trees": [{"pixel": [x, y], "nodes": [...]}, ...]}`; the answer gives each
    tree `{pixel, matches, differences: [{what, message, student, reference}], student, reference}`: the first
    difference first, `student` and `reference` the nodes' ids (null where that tree has no such ray)."""
    body = await request.body()
    return await owntrees.compare_log(
        course, jobs, lambda b: checks.summary(request.is_disconnected, b), tree_cache(request), caller, aid, sid,
        body, settings.max_tree_log_trees, request.is_disconnected,
    )  # fmt: skip


@router.get(
    "/{aid}/submissions/{sid}/trees",
    summary="The latest tree log comparison of a submission (its student's, or the staff's view of it)",
    responses={404: {"model": ErrorResponse, "description": "no such submission, or no log compared yet"}},
)
async def latest_trees(aid: str, sid: str, course: CourseDep, caller: CallerDep) -> dict:
    """The answer of the last POST to .../trees for this submission, as it was given."""
    return await owntrees.latest(course, caller, aid, sid)
