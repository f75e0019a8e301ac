"""Validation, the JSON Schema, the ray tree of one pixel, and health."""

from __future__ import annotations

import contextlib
import functools
import json

import anyio
from fastapi import APIRouter, Depends, Request, Response

from server.api.deps import (
    CallerDep,
    CapsDep,
    ChecksDep,
    ClientDep,
    JobsDep,
    KernelsDep,
    QueueDep,
    RunsDep,
    SettingsDep,
    StoreDep,
    get_client,
    still_waiting,
)
from server.api.models import ErrorResponse, Health, RayTreeRequest, ValidateRequest, WorkerInfo
from server.api.scene_route import scene_post
from server.core.clients import address_owner
from server.core.errors import Invalid
from server.jobs.lifecycle import ANONYMOUS_PRIORITY, RAYTREE_PRIORITY
from tracer.scene import scene_json_schema

router = APIRouter(prefix="/api", tags=["tools"])


@router.get("/health", summary="Liveness, the render workers (pids) and the jobs by status")
async def health(
    store: StoreDep, queue: QueueDep, checks: ChecksDep, jobs: JobsDep, runs: RunsDep, caller: CallerDep,
    kernels: KernelsDep,
) -> Health:  # fmt: skip
    """A worker's `job` is shown to the job's own token and to the instructor (null to anyone else). `status` is
    "starting" while the server loads the render kernels or a live worker is still loading them (a render waits in
    the queue meanwhile), else "ok"."""

    def answer() -> Health:  # reads the database (and, on Redis, the worker hosts): in one trip to a thread
        workers = queue.workers()
        if not caller.instructor:
            for w in workers:
                if w.get("job") and not caller.owns(store.get(w["job"]) or {}):
                    w["job"] = None
        starting = not kernels.is_set() or any(w.get("alive") and not w.get("ready") for w in workers)
        infos = [WorkerInfo.model_validate(w) for w in workers]
        return Health(status="starting" if starting else "ok", backend=queue.backend, queue=queue.stats,
                      workers=infos, checkers=checks.info(), jobs=store.counts(), followers=jobs.watch.followers(),
                      grading=runs.health())  # fmt: skip

    # async, so that FastAPI checks the answer here rather than in a second trip through the thread pool
    return await anyio.to_thread.run_sync(answer)


@functools.cache
def _schema_body() -> bytes:
    """The schema as the answer's bytes, made once: generating and encoding it took 25 ms of the API's CPU at each of
    the page's loads (every page asks for it)."""
    return json.dumps(scene_json_schema(), ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode()


@router.get(
    "/schema",
    summary="The scene format's JSON Schema (for editors)",
    response_class=Response,
    responses={200: {"content": {"application/json": {"schema": {"type": "object"}}}}},
)
def schema() -> Response:
    return Response(_schema_body(), media_type="application/json")


@scene_post(
    router,
    "/validate",
    summary="Check a scene: errors with JSON paths, and warnings",
    dependencies=[Depends(get_client)],  # TRACER_REQUIRE_IDENTITY: a known identity, else 401
    responses={401: {"model": ErrorResponse, "description": "TRACER_REQUIRE_IDENTITY, and no known identity"}},
)
async def validate(body: ValidateRequest, checks: ChecksDep, request: Request) -> dict:
    """`valid` is true when POST /api/jobs would accept the scene: the format, the service limits,
    and the asset files are all checked (in a checking process, server/checkers/pool.py: a scene that takes
    longer than TRACER_MAX_VALIDATE_SECONDS to check is not valid)."""
    try:
        return await checks.validate(request.is_disconnected, await request.body())
    except Invalid as exc:
        return {"valid": False, "errors": exc.errors, "warnings": []}


@scene_post(
    router,
    "/raytree",
    summary="The ray tree of one pixel sample (/reference/scene-format.md#the-ray-tree)",
    responses={
        401: {"model": ErrorResponse, "description": "TRACER_REQUIRE_IDENTITY, and no known identity"},
        422: {"model": ErrorResponse, "description": "invalid scene, or x, y, sample out of range"},
        429: {"model": ErrorResponse, "description": "the queue, the token's or the address's share of it is full"},
        503: {"model": ErrorResponse, "description": "no worker takes interactive work"},
        504: {"model": ErrorResponse, "description": "it took longer than TRACER_MAX_RAYTREE_SECONDS"},
    },
)
async def raytree(
    body: RayTreeRequest, jobs: JobsDep, settings: SettingsDep, checks: ChecksDep, client: ClientDep, caps: CapsDep,
    request: Request,
) -> dict:  # fmt: skip
    """Traced by a worker, as a short job of the interactive lane (never in the API process); a
    radiosity scene's solution is kept by its content, so only the first click on it solves it, and a
    solve estimated past the ray tree's time limit is refused before it starts unless its solution is
    kept. A client that gives up cancels it. The job belongs to the request's token, at the ray trees'
    priority (100); without a token, to the request's address, at an anonymous job's priority (0), counted
    under the address's caps (server/core/clients.py) like any of its anonymous work."""
    caller = client.caller
    waiting = None
    if client.capped:  # room under the address's cap, taken before the scene is checked
        waiting = await anyio.to_thread.run_sync(caps.waiting, client.address, still_waiting(jobs))
    with waiting or contextlib.nullcontext():
        found = await checks.summary(request.is_disconnected, await request.body())
        anonymous = caller.token is None and not caller.instructor
        return await jobs.raytree(
            found, (body.x, body.y, body.sample), priority=ANONYMOUS_PRIORITY if anonymous else RAYTREE_PRIORITY,
            owner=address_owner(client.address) if anonymous else caller.owner, gone=request.is_disconnected,
            name=f"ray tree ({body.x}, {body.y}) of {found['name'] or 'a scene'}",
            queued=(lambda row: waiting.keep(row["id"])) if waiting is not None else lambda row: None,
        )  # fmt: skip
