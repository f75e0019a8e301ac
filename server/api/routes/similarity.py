"""Similarity reports of an assignment (server/course/similarity.py, docs/assignments.md): the course's staff ask
for one (POST: 202, computed in a grading process) and read it (GET). Before assignments.py, whose routes would
not take these paths but whose prefix is the same."""

from __future__ import annotations

from fastapi import APIRouter, Request
from starlette.concurrency import run_in_threadpool

from server.api.deps import CallerDep, SimilarityDep, instructor_check
from server.api.models import ErrorResponse, Responses
from server.core.security import Caller
from server.course.similarity import Reports

router = APIRouter(prefix="/api/assignments", tags=["assignments"])
REFUSED: Responses = {
    403: {"model": ErrorResponse, "description": "a student of the assignment, or a token of no staff"},
    404: {"model": ErrorResponse, "description": "no such assignment"},
}


@router.post(
    "/{aid}/similarity",
    status_code=202,
    summary="Ask for a similarity report of the class's latest submissions (the course's staff)",
    responses={
        **REFUSED,
        413: {"model": ErrorResponse, "description": "more submissions (or bytes of them) than a report reads"},
        429: {"model": ErrorResponse, "description": "as many reports computing as the server runs at once"},
    },
)
async def ask(aid: str, request: Request, reports: SimilarityDep, caller: CallerDep) -> dict:
    """202 with `{status: "computing", started_at, students}`: the report is made in a grading process (seconds
    for a class of 300); GET the same address for it. Asked again while computing: the same answer."""
    return await run_in_threadpool(reports.ask, aid, caller, instructor_check(request))


@router.get(
    "/{aid}/similarity",
    summary="The latest similarity report: pairs much closer than the class's usual, for a person to look at",
    responses=REFUSED,
)
async def report(aid: str, request: Request, reports: SimilarityDep, caller: CallerDep) -> dict:
    """`{status, pairs: [{a, b, kind, score, typical, flagged, facts: [{path, a, b, shared}], facts_more}],
    closest, groups: {scene|image: {typical, spread, threshold, compared, candidates}}, skipped, students,
    computed_at, since, note, how}`. `status`: none (never asked), computing, done or failed. `score` is the
    pair's distance (0: the same), `typical` the class's median nearest-neighbour distance; `pairs` are the
    flagged ones, closest first; `closest` the nearest that were not flagged. `note` says what a flag means."""
    out = await run_in_threadpool(reports.get, aid, caller, instructor_check(request))
    return await run_in_threadpool(_anonymous, reports, aid, caller, request, out)


def _anonymous(reports: Reports, aid: str, caller: Caller, request: Request, out: dict) -> dict:
    """Under anonymous grading, until the release, a TA sees each pair's students as the grading queue's labels
    (server/course/manual.py `hides_names`)."""
    course = reports.course
    a, who = course.staff(aid, caller, instructor_check(request))
    if not course.hides_names(a, who):
        return out
    labels = course.anonymous_labels(a)

    def mask(pairs: list[dict]) -> list[dict]:
        return [{**p, "a": labels.get(p["a"], "Student ?"), "b": labels.get(p["b"], "Student ?")} for p in pairs]

    return {**out, **{k: mask(out[k]) for k in ("pairs", "closest") if isinstance(out.get(k), list)}}
