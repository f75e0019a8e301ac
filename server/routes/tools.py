"""Validation, the JSON Schema, the ray tree of one pixel, and health."""

from __future__ import annotations

import json
import time

import anyio
from fastapi import APIRouter, Request

from server.deps import QueueDep, SettingsDep, StoreDep
from server.errors import ApiError
from server.lifecycle import JobKind, JobStatus, Lane
from server.models import ErrorResponse, Health, RayTreeRequest, ValidateRequest
from server.routes.jobs import check_scene, create_job
from server.store import JobFile
from tracer.scene import scene_json_schema

router = APIRouter(prefix="/api", tags=["tools"])

RAYTREE_POLL = 0.01  # seconds between two looks at a ray tree's job


@router.get("/health", summary="Liveness, the render workers (pids) and the jobs by status")
def health(store: StoreDep, queue: QueueDep) -> Health:
    return Health(status="ok", backend=queue.backend, queue=queue.stats, workers=queue.workers(), jobs=store.counts())


@router.get("/schema", summary="The scene format's JSON Schema (for editors)")
def schema() -> dict:
    return scene_json_schema()


@router.post("/validate", summary="Check a scene: errors with JSON paths, and warnings")
def validate(body: ValidateRequest, settings: SettingsDep) -> dict:
    """`valid` is true when POST /api/jobs would accept the scene: the format, the service limits,
    and the asset files are all checked."""
    try:
        _, warnings = check_scene(body.scene, settings)
    except ApiError as exc:
        return {"valid": False, "errors": exc.errors, "warnings": []}
    return {"valid": True, "errors": [], "warnings": warnings}


@router.post(
    "/raytree",
    summary="The ray tree of one pixel sample (/reference/scene-format.md#the-ray-tree)",
    responses={
        422: {"model": ErrorResponse, "description": "invalid scene, or x, y, sample out of range"},
        503: {"model": ErrorResponse, "description": "no worker takes interactive work"},
        504: {"model": ErrorResponse, "description": "it took longer than TRACER_MAX_RAYTREE_SECONDS"},
    },
)
async def raytree(
    body: RayTreeRequest, settings: SettingsDep, store: StoreDep, queue: QueueDep, request: Request
) -> dict:
    """Traced by a worker, as a short job of the interactive lane (never in the API process); a
    radiosity scene's solution is kept by its content, so only the first click on it solves it. A
    client that gives up cancels it."""
    scene, _ = await anyio.to_thread.run_sync(check_scene, body.scene, settings)
    d = scene.film
    errors = [
        {"path": k, "message": f"must be a {what} in 0..{n - 1}"}
        for k, v, n, what in (("x", body.x, d.width, "column"), ("y", body.y, d.height, "row"))
        if not 0 <= v < n
    ]
    if errors:
        raise ApiError(422, errors)
    if queue.capacity(Lane.interactive) == 0:
        raise ApiError(503, "no render worker takes interactive work: start one (TRACER_WORKERS, or a worker host)")
    params = {"x": body.x, "y": body.y, "sample": body.sample}
    row = create_job(
        store, settings, scene, body.scene, kind=JobKind.raytree, lane=Lane.interactive, priority=100,
        params=params, max_seconds=settings.max_raytree_seconds, samples_total=1, warnings=[],
        name=f"ray tree ({body.x}, {body.y}) of {scene.name or 'a scene'}"[:200],
    )  # fmt: skip
    queue.submitted(row)
    deadline = time.monotonic() + settings.max_raytree_seconds + 10
    while True:
        row = await anyio.to_thread.run_sync(store.get, row["id"])
        if JobStatus(row["status"]).finished:
            break
        stopping = request.app.state.stopping()
        if stopping or await request.is_disconnected() or time.monotonic() > deadline:
            cancelled = await anyio.to_thread.run_sync(store.cancel, row["id"])
            queue.cancelled(cancelled)
            if stopping:
                raise ApiError(503, "the server is stopping: ask again once it is back", headers={"Retry-After": "5"})
            if time.monotonic() > deadline:
                raise ApiError(504, f"the ray tree took longer than {settings.max_raytree_seconds:g} s")
            raise ApiError(499, "the client went away")
        await anyio.sleep(RAYTREE_POLL)
    if row["status"] == JobStatus.done:
        text = await anyio.to_thread.run_sync(store.job_file(row["id"], JobFile.raytree).read_text)
        return json.loads(text)
    errors = json.loads(row["errors"] or "[]")
    if errors:
        raise ApiError(422, errors)
    raise ApiError(503, row["error"] or f"the ray tree's job was {row['status']}")
