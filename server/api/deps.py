"""Dependencies of the routes, as `Annotated` aliases: the settings, the job service (and its store), the job
queue's interface, the scene checking processes, a job (the caller's own: server/core/security.py)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Path, Request

from server.checkers.pool import CheckPool
from server.core.errors import ApiError
from server.core.ids import looks_like_job_id
from server.core.security import CallerDep
from server.core.settings import Settings
from server.jobs.service import JobService
from server.jobs.store import JobStore
from server.queue.base import JobQueue


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_store(request: Request) -> JobStore:
    return request.app.state.store


def get_queue(request: Request) -> JobQueue:
    return request.app.state.queue


def get_jobs(request: Request) -> JobService:
    return request.app.state.jobs


def get_checks(request: Request) -> CheckPool:
    return request.app.state.checks


SettingsDep = Annotated[Settings, Depends(get_settings)]
StoreDep = Annotated[JobStore, Depends(get_store)]
QueueDep = Annotated[JobQueue, Depends(get_queue)]
ChecksDep = Annotated[CheckPool, Depends(get_checks)]
JobsDep = Annotated[JobService, Depends(get_jobs)]


def get_job(
    job_id: Annotated[str, Path(description="the job's id, as POST /api/jobs returned it")],
    store: StoreDep,
    caller: CallerDep,
    request: Request,
):
    """The job's row, or 404 (ids that cannot be ours are refused before the database sees them). A job
    of another token is the same 404 as an unknown id: ids are never confirmed. The job's share token
    reads it (GET) and nothing more."""
    row = store.get(job_id) if looks_like_job_id(job_id) else None
    if row is None or not (caller.owns(row) or (request.method == "GET" and caller.shares(row))):
        raise ApiError(404, [{"path": "id", "message": f"no job with id '{job_id[:64]}'"}])
    return row


JobDep = Annotated[dict, Depends(get_job)]
