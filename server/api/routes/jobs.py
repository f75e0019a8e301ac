"""Render jobs: submit, list, inspect, fetch the latest image, follow the events, cancel.

A job belongs to the token that submitted it (server/core/security.py): every route of one job answers
only that token (or the instructor), and anyone else gets the 404 of an unknown id."""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import AsyncGenerator
from typing import Annotated, Literal

import anyio
from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import StreamingResponse

from server.api.deps import (
    CallerDep,
    CapsDep,
    ChecksDep,
    ClientDep,
    JobDep,
    JobsDep,
    StoreDep,
    client_address,
    still_waiting,
)
from server.api.errors import ApiError
from server.api.models import ErrorResponse, JobCreate, JobCreated, JobList, JobPublic, Responses
from server.api.scene_route import scene_post
from server.api.streams import KEEP_ALIVE, event_stream, sse
from server.core.errors import NotFound
from server.core.security import new_token, share_token, token_hash, unauthorized
from server.jobs.files import AOV_NAMES, JobFile
from server.jobs.lifecycle import JobKind, JobStatus
from server.jobs.rows import JobRow
from server.jobs.service import JobService
from server.jobs.store import JobStore

router = APIRouter(prefix="/api/jobs", tags=["jobs"])

MAX_QUERY_INT = 1_000_000_000  # bound of the integer query parameters (offset, pass): SQLite's integers end at 2**63
ERRORS: Responses = {422: {"model": ErrorResponse, "description": "invalid request or scene, with JSON paths"}}
UNAUTHORIZED: Responses = {401: {"model": ErrorResponse, "description": "a malformed Authorization header"}}
NOT_FOUND: Responses = {
    404: {"model": ErrorResponse, "description": "no such job, or not this token's job (the same answer)"},
    **UNAUTHORIZED,
}


@scene_post(
    router,
    "",
    status_code=202,
    summary="Submit a scene for rendering",
    responses={
        **ERRORS,
        401: {
            "model": ErrorResponse,
            "description": "a malformed Authorization header; with TRACER_REQUIRE_IDENTITY, no token of a "
            "roster or the instructor's",
        },
        413: {"model": ErrorResponse, "description": "request body too large"},
        429: {
            "model": ErrorResponse,
            "description": "too many jobs in the queue, a token's renders waiting or running past its share "
            "(TRACER_MAX_ACTIVE_JOBS_PER_TOKEN), or new tokens or waiting jobs of one address without a known "
            "identity",
        },
    },
)
async def submit(
    body: JobCreate, jobs: JobsDep, checks: ChecksDep, client: ClientDep, caps: CapsDep, request: Request,
    response: Response,
) -> JobCreated:  # fmt: skip
    """Validate the scene (422 with `errors: [{path, message}]`), queue it by lane, priority and age (202).

    A render estimated to take longer than the per-job limit is refused (422); one estimated past
    TRACER_INTERACTIVE_SECONDS goes to the batch lane. `lane: batch` moves a job down; only the instructor may
    move one up (`lane: interactive`) or give it a priority above 0: anyone else's is lowered (to the estimate's
    lane, to 0), with a warning at `lane` or `priority`. A token other than the instructor's has at most
    TRACER_MAX_ACTIVE_JOBS_PER_TOKEN renders waiting or running (its share of the workers): 429 past it. The job
    comes back with the scene's `warnings`, its `estimate` and its place in the queue; follow it at `events_url`.
    The scene is validated in a checking process (server/checkers/pool.py), as the worker will, its asset
    files resolved in the asset folder (a mesh read and its triangles counted, an image's header read).

    The job belongs to the request's token (`Authorization: Bearer <token>`); a request without one gets
    a fresh token in `token`: only that token reads, follows, cancels and downloads the job. One address gets
    so many new tokens, and has so many jobs waiting without a known identity (a roster's token or the
    instructor's), before a 429 (server/core/clients.py); TRACER_REQUIRE_IDENTITY refuses those with a 401."""
    caller = client.caller
    with contextlib.ExitStack() as rooms:  # room under the address's caps, taken before the scene is checked
        new = None
        if caller.token is None and not client.known:  # (known: on a loopback-only server with no instructor)
            new = rooms.enter_context(caps.new_token(client.address))
        waiting = None
        if client.capped:  # (a joined identity too: a name anyone may type)
            taken = await anyio.to_thread.run_sync(caps.waiting, client.address, still_waiting(jobs))
            waiting = rooms.enter_context(taken)
        found = await checks.summary(request.is_disconnected, await request.body())
        issued = new_token() if caller.token is None else None
        settings = jobs.settings

        def queued() -> JobCreated:
            seconds = jobs.estimate(found)
            placed = jobs.place(seconds, body.lane, body.priority, staff=caller.instructor)
            row = jobs.submit_checked(
                found,
                priority=placed.priority,
                warnings=[*found["warnings"], *placed.warnings],
                estimate=seconds,
                lane=placed.lane,
                owner=caller.owner or (token_hash(issued) if issued is not None else None),
                max_active_owner=None if caller.instructor else settings.max_active_jobs_per_token,
            )
            for room in (new, waiting):
                if room is not None:
                    room.keep(row["id"])
            response.headers["Location"] = f"/api/jobs/{row['id']}"
            return JobCreated(**jobs.public(row).model_dump(), token=issued)

        return await anyio.to_thread.run_sync(queued)


@router.get("", summary="The caller's jobs (the instructor: every job), newest first", responses=UNAUTHORIZED)
def list_jobs(
    jobs: JobsDep,
    caller: CallerDep,
    caps: CapsDep,
    request: Request,
    status: Annotated[JobStatus | None, Query(description="only jobs with this status")] = None,
    kind: Annotated[JobKind | None, Query(description="only jobs of this kind (default render)")] = JobKind.render,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
    offset: Annotated[int, Query(ge=0, le=MAX_QUERY_INT)] = 0,
    scope: Annotated[
        Literal["mine", "all"] | None,
        Query(
            description="mine: the jobs of the request's token; all: every job (the instructor only, else 401); "
            "default: all for the instructor, mine for anyone else"
        ),
    ] = None,
) -> JobList:
    """A student sees the jobs of their token (none without one); the instructor (TRACER_INSTRUCTOR_TOKEN,
    or anyone on a loopback-only server without one) every job, grading renders included."""
    if scope == "all" and not caller.instructor:
        if caller.token is not None:  # a token that is not the instructor's: counted against the address
            caps.auth_failed(client_address(request))
        raise unauthorized("listing every job needs the instructor's token (TRACER_INSTRUCTOR_TOKEN)", "")
    if scope == "mine" or not caller.instructor:
        if caller.owner is None:
            return JobList(jobs=[], count=0)
        owner = caller.owner
    else:
        owner = None
    kinds = kind.value if kind else None
    rows, count = jobs.store.list_jobs(status.value if status else None, limit, offset, kinds, owner=owner)
    now = time.time()
    return JobList(jobs=[jobs.public(r, now) for r in rows], count=count)


@router.get(
    "/{job_id}", summary="One job: status, place in the queue, progress, elapsed and ETA, rays", responses=NOT_FOUND
)
async def get_job(job: JobDep, jobs: JobsDep) -> JobPublic:
    # the view of a running or ended job is made from its row alone, here; a queued one's place is a query, in a
    # thread (each trip through the thread pool waits for the event loop, which 500 streams keep busy)
    if job["status"] == JobStatus.queued:
        return await anyio.to_thread.run_sync(jobs.public, job)
    return jobs.public(job)


@router.get(
    "/{job_id}/image",
    summary="The latest image: progressive while running, final when done",
    response_class=Response,
    responses={
        200: {"content": {"image/png": {}, "image/x-exr": {}}, "description": "PNG (sRGB), or EXR (linear float)"},
        **NOT_FOUND,
    },
)
def image(
    job: JobDep,
    store: StoreDep,
    format: Annotated[
        Literal["png", "exr"], Query(description="png: sRGB with the film's exposure; exr: linear")
    ] = "png",
    pass_: Annotated[
        int | None, Query(alias="pass", ge=0, le=MAX_QUERY_INT, description="ignored; makes each pass's URL new")
    ] = None,
) -> Response:
    if not job["preview"]:
        raise ApiError(404, f"no image yet: the job is {job['status']}")
    try:
        data = store.job_file(job["id"], JobFile.image(format)).read_bytes()
    except FileNotFoundError:
        raise ApiError(404, "the job's image is missing from the data directory") from None
    media = "image/png" if format == "png" else "image/x-exr"
    headers = {
        "Cache-Control": "no-store",
        "Content-Disposition": f'inline; filename="job-{job["id"]}.{format}"',
    }
    return Response(data, media_type=media, headers=headers)


@router.post("/{job_id}/share", summary="A read-only link to the job: its share token", responses=NOT_FOUND)
def share(job: JobDep) -> dict:
    """The job's share token, which reads this job only (its GET routes: the job, events, image, AOVs, scene,
    radiosity) and cancels nothing; and the page's read-only link. The token goes in the link's fragment,
    which browsers never send to the server. Only the job's owner (or the instructor) asks for it."""
    token = share_token(job)
    if token is None:
        raise ApiError(409, [{"path": "id", "message": "a job with no owner (a grading render) cannot be shared"}])
    return {"share_token": token, "link": f"/#shared/{job['id']}/{token}"}


@router.get("/{job_id}/scene", summary="The scene the job renders, as it was submitted", responses=NOT_FOUND)
def job_scene(job: JobDep, store: StoreDep) -> dict:
    """For a client that shows an older job: its ray tree needs the very scene it rendered."""
    row = store.get(job["id"])  # JobDep's row has no scene (a student's may be megabytes: not read in the loop)
    if row is None:
        raise ApiError(404, [{"path": "id", "message": f"no job with id '{job['id'][:64]}'"}])
    return json.loads(row["scene"])


def _aov_ready(job: JobRow, store: JobStore) -> dict[str, list[float]]:
    if job["status"] != JobStatus.done:
        raise ApiError(404, f"no AOVs: they are saved when the job is done, and it is {job['status']}")
    try:
        return json.loads(store.job_file(job["id"], JobFile.aov_ranges).read_text())
    except FileNotFoundError:
        params = job.get("params") or {}
        if (json.loads(params) if isinstance(params, str) else params).get("outputs") == "floats":
            raise ApiError(404, "no AOV pictures: this job rendered for grading, which keeps only its image") from None
        raise ApiError(404, "the job's AOVs are missing from the data directory") from None


@router.get(
    "/{job_id}/radiosity", summary="A finished radiosity job's solution: patches, convergence", responses=NOT_FOUND
)
def radiosity(job: JobDep, store: StoreDep) -> Response:
    """`patches` (corner, e1, e2, triangle, normal, area, object, reflectance, emission; the second half
    are the backs of the first), `radiosity` (B per patch side, W/m^2), `energy` (emitted, absorbed,
    unshot, escaped), `history` (per shot: shooter, power, unshot left) and `snapshots` (B after every
    shot up to 16, then 32, 64, ..., and the last), for showing which patch shoots, step by step."""
    if job["status"] != JobStatus.done:
        raise ApiError(404, f"no radiosity solution: it is saved when the job is done, and it is {job['status']}")
    try:
        data = store.job_file(job["id"], JobFile.radiosity).read_bytes()
    except FileNotFoundError:
        raise ApiError(404, "this job has no radiosity solution (its integrator is not radiosity)") from None
    return Response(data, media_type="application/json")


@router.get("/{job_id}/aov", summary="The AOV pictures of a finished job and the range of each", responses=NOT_FOUND)
def aov_list(job: JobDep, store: StoreDep) -> dict:
    """`names`; `ranges` {name: [min, max]} of the values the pictures show (rays per pixel, depth, ...)."""
    ranges = _aov_ready(job, store)
    return {"names": [n for n in AOV_NAMES if n in ranges], "ranges": ranges}


@router.get(
    "/{job_id}/aov/{name}",
    summary="One AOV of a finished job as a PNG",
    response_class=Response,
    responses={200: {"content": {"image/png": {}}}, **NOT_FOUND},
)
def aov_image(job: JobDep, store: StoreDep, name: str) -> Response:
    """rays: rays per pixel as a heat map (black 0, white the maximum); depth: near white, far dark, black
    where nothing was hit; normal: 0.5 + 0.5 n; albedo: kd (sRGB); variance: per-pixel variance as a heat map."""
    if name not in AOV_NAMES:
        message = f"no AOV named '{name[:64]}'; one of: {', '.join(AOV_NAMES)}"
        raise ApiError(404, [{"path": "name", "message": message}])
    _aov_ready(job, store)
    try:
        data = store.job_file(job["id"], JobFile.aov(name)).read_bytes()
    except FileNotFoundError:
        raise ApiError(404, [{"path": "name", "message": f"the job has no '{name}' AOV"}]) from None
    headers = {"Cache-Control": "no-store", "Content-Disposition": f'inline; filename="job-{job["id"]}-{name}.png"'}
    return Response(data, media_type="image/png", headers=headers)


@router.get(
    "/{job_id}/events",
    summary="Server-Sent Events: progress, preview (a new image), end",
    response_class=StreamingResponse,
    responses={
        200: {"content": {"text/event-stream": {}}},
        429: {"model": ErrorResponse, "description": "too many event streams open for one token or one address"},
        **NOT_FOUND,
    },
)
def events(job: JobDep, jobs: JobsDep, caller: CallerDep, request: Request) -> StreamingResponse:
    """`progress` {status, samples_done, samples_total, fraction, passes_done, spp_done, phase, solve, elapsed,
    eta, rays};
    `preview` {pass, spp, url, exr_url} when a new image is on disk; `end` {the job}, then the stream closes.
    The stream is woken when the job's row changes (the job service's watcher): it never polls the store.
    One token, and one address, may have so many streams open (429 past TRACER_MAX_STREAMS_PER_TOKEN or
    TRACER_MAX_STREAMS_PER_ADDRESS)."""
    return event_stream(request, caller, _events(jobs, job["id"]))


# a view's events as text, made once for all the streams it wakes (the job service shares one view of a row
# among its followers: 250 streams on one render format its progress once, not 250 times): id of the view ->
# (the view, kept so that its id stays its own, its texts); the oldest go past TEXTS_KEPT
_TEXTS: dict[int, tuple[JobPublic, tuple]] = {}
TEXTS_KEPT = 4096


def _texts(job: JobPublic, job_id: str) -> tuple:
    """(what the progress says, its `progress` event, the `preview` event or None, the `end` event or None)."""
    kept = _TEXTS.get(id(job))
    if kept is not None and kept[0] is job:
        return kept[1]
    p = job.progress
    place = job.queue.model_dump(mode="json") if job.queue else None
    at = (job.status, p.samples_done, p.passes_done, p.solve.shots if p.solve else 0, json.dumps(place))
    data = dict(status=job.status.value, **p.model_dump(), elapsed=job.elapsed, eta=job.eta, rays=job.rays)
    data.update(queue=place, finished=job.finished)
    preview = None
    if job.preview:
        base = f"/api/jobs/{job_id}/image"
        shown = {"pass": job.preview, "spp": p.spp_done, "url": f"{base}?pass={job.preview}"}
        shown["exr_url"] = f"{base}?format=exr&pass={job.preview}"
        preview = sse("preview", shown)
    end = sse("end", job.model_dump(mode="json")) if job.status.finished else None
    texts = (at, sse("progress", data), preview, end)
    _TEXTS[id(job)] = (job, texts)
    while len(_TEXTS) > TEXTS_KEPT:
        del _TEXTS[next(iter(_TEXTS))]
    return texts


async def _events(jobs: JobService, job_id: str) -> AsyncGenerator[str, None]:
    last_progress, last_preview = None, 0
    # no question whether the client left: Starlette's StreamingResponse listens for the disconnect itself and
    # cancels this stream (uvicorn says ASGI 2.3), or its next write fails (2.4: at the latest the keep-alive's);
    # Request.is_disconnected once a second from each of 500 streams took a tenth of the event loop's time
    async for job in jobs.follow(job_id):
        if job is None:
            yield KEEP_ALIVE
            continue
        at, progress, preview, end = _texts(job, job_id)
        out = []  # one write for all a change says (each write goes through the middlewares and h11)
        if at != last_progress:
            last_progress = at
            out.append(progress)
        if preview is not None and job.preview != last_preview:
            last_preview = job.preview
            out.append(preview)
        if end is not None:
            out.append(end)
        if out:
            yield "".join(out)
        if end is not None:
            return


@router.delete(
    "/{job_id}",
    summary="Cancel a queued or running job",
    responses={
        202: {"model": JobPublic, "description": "running: it stops within one band of rows, keeping its last image"},
        409: {"model": ErrorResponse, "description": "the job has already ended"},
        **NOT_FOUND,
    },
)
def cancel(job: JobDep, jobs: JobsDep, response: Response) -> JobPublic:
    """A queued job is cancelled at once (200); a running one is asked to stop (202) and ends `cancelled`,
    even if its render finishes before it sees the request; a job that has ended is 409 (the job's row
    decides, in one transaction: the answer always agrees with the job's final status)."""
    if JobStatus(job["status"]).finished:
        raise ApiError(409, f"the job has already ended ({job['status']})")
    row = jobs.cancel(job["id"])
    if row is None:  # deleted since it was read (the janitor): as any unknown id
        raise NotFound.at("id", f"no job with id '{job['id']}'")
    if JobStatus(row["status"]) in (JobStatus.done, JobStatus.failed):  # it ended between the two reads
        raise ApiError(409, f"the job has already ended ({row['status']})")
    if JobStatus(row["status"]) is JobStatus.running:
        response.status_code = 202
    return jobs.public(row)
