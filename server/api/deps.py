"""Dependencies of the routes, as `Annotated` aliases, in this one place: the settings, the job service (and its
store), the job queue's interface, the scene checking processes, the course, the LTI tool and the LMS, who calls
(`CallerDep`) and whether they are the instructor (`InstructorDep`, `require_instructor`; the rules are
server/core/security.py's), a job (the caller's own), and who asks for work from which address (the caps of
anonymous clients: server/core/clients.py).

Those that only look something up are `async def`: FastAPI runs a plain `def` dependency in its thread pool,
a trip through another thread (and the interpreter's lock) for each, which a busy event loop makes slow."""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

import anyio
from fastapi import Depends, Path, Request
from fastapi.security import HTTPBearer

from server.checkers.pool import CheckPool
from server.core.clients import AddressCaps
from server.core.errors import NotFound, Unavailable
from server.core.ids import looks_like_job_id
from server.core.security import Caller, check_instructor, is_instructor, parse_bearer, token_hash, unauthorized
from server.core.settings import Settings
from server.course.lms import Lms
from server.course.owntrees import TreeCache
from server.course.service import Course
from server.course.similarity import Reports
from server.grading.runs import GradeRuns
from server.jobs.janitor import Janitor
from server.jobs.lifecycle import JobStatus
from server.jobs.previews import Previews
from server.jobs.rows import JobRow
from server.jobs.service import JobService
from server.jobs.store import JobStore
from server.lti.tool import LtiTool
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


async def get_course(request: Request) -> Course:
    return request.app.state.course


async def get_tree_cache(request: Request) -> TreeCache:
    return request.app.state.tree_cache


async def get_similarity(request: Request) -> Reports:
    return request.app.state.similarity


async def get_lti(request: Request) -> LtiTool:
    return request.app.state.lti


async def get_runs(request: Request) -> GradeRuns:
    return request.app.state.grade_runs


async def get_previews(request: Request) -> Previews:
    return request.app.state.previews


async def get_stopping(request: Request) -> Callable[[], bool]:
    """Whether the server has been asked to stop (server/main.py's `Stopping`): an event stream ends then."""
    return request.app.state.stopping


async def get_kernels(request: Request) -> threading.Event:
    """Set once the render kernels are loaded (server/main.py: in a thread after start-up; the workers then start)."""
    return request.app.state.kernels


async def find_janitor(request: Request) -> Janitor | None:
    """The janitor (the data directory's size as it last measured it), None before the server has started."""
    return getattr(request.app.state, "janitor", None)


async def find_lms(request: Request) -> Lms | None:
    """The course's side of LTI, None where it is not running."""
    return getattr(request.app.state, "lms", None)


def get_lms(request: Request) -> Lms:
    """The course's side of LTI; 503 where it is not running. Called by its routes after their own checks (a
    caller refused, an unknown course: those answers come first), so it is no dependency."""
    lms = getattr(request.app.state, "lms", None)
    if lms is None:
        raise Unavailable.at("", "LTI is not running on this server")
    return lms


SettingsDep = Annotated[Settings, Depends(get_settings)]
StoreDep = Annotated[JobStore, Depends(get_store)]
QueueDep = Annotated[JobQueue, Depends(get_queue)]
ChecksDep = Annotated[CheckPool, Depends(get_checks)]
JobsDep = Annotated[JobService, Depends(get_jobs)]
CapsDep = Annotated[AddressCaps, Depends(get_caps)]
CourseDep = Annotated[Course, Depends(get_course)]
TreeCacheDep = Annotated[TreeCache, Depends(get_tree_cache)]  # the reference's trees of own tracers' logs
SimilarityDep = Annotated[Reports, Depends(get_similarity)]  # similarity reports (server/course/similarity.py)
LtiDep = Annotated[LtiTool, Depends(get_lti)]
MaybeLmsDep = Annotated[Lms | None, Depends(find_lms)]
MaybeJanitorDep = Annotated[Janitor | None, Depends(find_janitor)]
RunsDep = Annotated[GradeRuns, Depends(get_runs)]
PreviewsDep = Annotated[Previews, Depends(get_previews)]
StoppingDep = Annotated[Callable[[], bool], Depends(get_stopping)]
KernelsDep = Annotated[threading.Event, Depends(get_kernels)]


# -- who calls -------------------------------------------------------------------------------------

bearer = HTTPBearer(
    auto_error=False,
    scheme_name="token",
    description="A job's token (POST /api/jobs issues one when none is sent), or the instructor's "
    "(TRACER_INSTRUCTOR_TOKEN) for grading and every job.",
)


def client_address(request: Request) -> str | None:
    """The address the request came from (None where the server cannot say): what the caps of anonymous clients
    count by (server/core/clients.py)."""
    return request.client.host if request.client else None


async def get_caller(request: Request, _: Annotated[object, Depends(bearer)] = None) -> Caller:
    """The caller of a request (`_`: only so that /docs offers a field for the token). `async`: it reads nothing
    but the request (no trip through the thread pool)."""
    token = parse_bearer(request.headers.get("authorization"))
    owner = token_hash(token) if token else None
    instructor = is_instructor(token, request.app.state.settings)
    caps, address = request.app.state.caps, client_address(request)
    if token is not None and not instructor and caps.auth_held(address) and not _known_token(request, owner):
        # an address that sent too many refused tokens waits (server/core/clients.py); a good token never does
        caps.auth_allowed(address)
    return Caller(token, owner, instructor)


def _known_token(request: Request, owner: str | None) -> bool:
    """Whether the token of hash `owner` is a course's (a roster's, a joined student's or a staff member's): a
    good token, which the failed-auth backoff never holds up. Asked only while an address is held."""
    course = request.app.state.course
    return owner is not None and course is not None and course.store.roster_kind(owner) is not None


CallerDep = Annotated[Caller, Depends(get_caller)]


def instructor_check(request: Request) -> Callable[[Caller], Caller]:
    """`check_instructor` for this request's server, a refused token counted against its address: what the course
    service is handed to decide about a caller who is none of a course's staff (`Course.staff`)."""
    caps, address = request.app.state.caps, client_address(request)
    return lambda caller: check_instructor(caller, request.app.state.settings, lambda: caps.auth_failed(address))


def require_instructor(caller: CallerDep, request: Request) -> Caller:
    """401 unless the caller is the instructor (403 on a server that has no instructor)."""
    return instructor_check(request)(caller)


InstructorDep = Annotated[Caller, Depends(require_instructor)]


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
        raise NotFound.at("id", f"no job with id '{job_id[:64]}'")
    return row


JobDep = Annotated[JobRow, Depends(get_job)]


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
    address = client_address(request)
    if not known and request.app.state.settings.require_identity:
        if caller.token is None:
            raise unauthorized(NO_TOKEN, "")
        request.app.state.caps.auth_failed(address)  # a token where a known one is needed: counted
        raise unauthorized(NOT_ON_A_ROSTER)
    return Client(caller, address, known, capped=not (caller.instructor or listed == "roster"))


ClientDep = Annotated[Client, Depends(get_client)]


def still_waiting(jobs: JobService):
    """For the caps of anonymous clients: which of these job ids are still waiting in the queue."""
    return lambda ids: [i for i, row in jobs.store.states(ids).items() if row["status"] == JobStatus.queued]
