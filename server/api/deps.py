"""Dependencies of the routes, as `Annotated` aliases: the settings, the job service (and its store), the job
queue's interface, the scene checking processes, a job (the caller's own: server/core/security.py), and who asks
for work from which address (the caps of anonymous clients: server/core/clients.py).

Those that only look something up are `async def`: FastAPI runs a plain `def` dependency in its thread pool,
a trip through another thread (and the interpreter's lock) for each, which a busy event loop makes slow."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import anyio
from fastapi import Depends, Path, Request
from fastapi.responses import StreamingResponse

from server.checkers.pool import CheckPool
from server.core.clients import AddressCaps
from server.core.errors import ApiError
from server.core.ids import looks_like_job_id
from server.core.security import Caller, CallerDep, unauthorized
from server.core.settings import Settings
from server.jobs.lifecycle import JobStatus
from server.jobs.service import JobService
from server.jobs.store import JobStore
from server.queue.base import JobQueue


async def get_settings(request: Request) -> Settings:
    return request.app.state.settings


async def get_store(request: Request) -> JobStore:
    return request.app.state.store


async def get_queue(request: Request) -> JobQueue:
    return request.app.state.queue


async def get_jobs(request: Request) -> JobService:
    return request.app.state.jobs


async def get_checks(request: Request) -> CheckPool:
    return request.app.state.checks


async def get_caps(request: Request) -> AddressCaps:
    return request.app.state.caps


SettingsDep = Annotated[Settings, Depends(get_settings)]
StoreDep = Annotated[JobStore, Depends(get_store)]
QueueDep = Annotated[JobQueue, Depends(get_queue)]
ChecksDep = Annotated[CheckPool, Depends(get_checks)]
JobsDep = Annotated[JobService, Depends(get_jobs)]
CapsDep = Annotated[AddressCaps, Depends(get_caps)]


async def get_job(
    job_id: Annotated[str, Path(description="the job's id, as POST /api/jobs returned it")],
    store: StoreDep,
    caller: CallerDep,
    request: Request,
):
    """The job's row without its scene, or 404 (ids that cannot be ours are refused before the database sees
    them). A job of another token is the same 404 as an unknown id: ids are never confirmed. The job's share
    token reads it (GET) and nothing more. Read here, in the event loop (a trip through the thread pool waits
    for the loop twice, which a class's event streams keep busy), unless the read would wait for a lock."""
    row = None
    if looks_like_job_id(job_id):
        try:
            row = store.peek(job_id)
        except sqlite3.OperationalError:
            row = await anyio.to_thread.run_sync(store.peek, job_id, True)
    if row is None or not (caller.owns(row) or (request.method == "GET" and caller.shares(row))):
        raise ApiError(404, [{"path": "id", "message": f"no job with id '{job_id[:64]}'"}])
    return row


JobDep = Annotated[dict, Depends(get_job)]


# -- who asks for work -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Client:
    """Who asks for work (a job, a ray tree, a scene checked), from which address, and whether their identity is
    known: the instructor, or a student on some assignment's roster (their token's hash is their owner)."""

    caller: Caller
    address: str | None
    known: bool
    capped: bool = True  # under its address's caps: anyone but the instructor and a roster's student (a joined
    # identity, a name anyone may type, is known but capped)


NO_TOKEN = (
    "this server works only for the students of its course (TRACER_REQUIRE_IDENTITY): open your assignment's link "
    "first (it carries your token), or ask your instructor for it"
)
NOT_ON_A_ROSTER = (
    "this token is on no assignment's roster (TRACER_REQUIRE_IDENTITY), so this server does no work for it: open "
    "your assignment's link again (an open assignment's page lets you join by your name), or ask your instructor "
    "for a new link"
)


def get_client(request: Request, caller: CallerDep) -> Client:
    """The client asking for work; with TRACER_REQUIRE_IDENTITY, 401 unless their identity is known (a refused
    token counts against its address: server/core/clients.py)."""
    course = request.app.state.course
    listed = course.store.roster_kind(caller.owner) if caller.owner is not None and course is not None else None
    known = caller.instructor or listed is not None
    address = request.client.host if request.client else None
    if not known and request.app.state.settings.require_identity:
        if caller.token is None:
            raise unauthorized(NO_TOKEN, "")
        request.app.state.caps.auth_failed(address)  # a token where a known one is needed: counted
        raise unauthorized(NOT_ON_A_ROSTER)
    return Client(caller, address, known, capped=not (caller.instructor or listed == "roster"))


ClientDep = Annotated[Client, Depends(get_client)]


# -- event streams ---------------------------------------------------------------------------------


class CappedStream(StreamingResponse):
    """An event stream that holds room under its client's caps of open streams (server/core/clients.py,
    `StreamCaps`) and gives it back when it ends, however it ends (finished, the client gone, the server
    stopping)."""

    def __init__(self, content, release: Callable[[], None], **kwargs):
        super().__init__(content, **kwargs)
        self.release = release

    async def __call__(self, scope, receive, send) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            self.release()


def stream_room(request: Request, caller: Caller) -> Callable[[], None]:
    """Room for one more open event stream of this caller (their token and their address); 429 past a cap. The
    instructor's streams are not counted. The answer gives it back: hand it to a `CappedStream`."""
    if caller.instructor:
        return lambda: None
    return request.app.state.streams.open(caller.owner, request.client.host if request.client else None)


def still_waiting(jobs: JobService):
    """For the caps of anonymous clients: which of these job ids are still waiting in the queue."""
    return lambda ids: [i for i, row in jobs.store.states(ids).items() if row["status"] == JobStatus.queued]
