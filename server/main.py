"""The FastAPI application: API routers under /api, the static page from web/ at /.

At start-up (the lifespan) the app checks its data directory and takes its lock (server/core/startup.py), brings
its database to this release's schema (server/core/migrations.py: a copy first, if it is older), opens the job
store, puts back in the queue the jobs a dead server left running, has the processes that check scenes
(server/checkers/pool.py) and then the render workers started once their kernels are loaded (compiled, or read
from Warp's cache, in a thread started last, while the page answers; a render waits in the queue meanwhile, and
/api/health says "starting"), resumes the grading runs a stopped server left unfinished (the course's
assignments' among them, with the submissions it had accepted but not handed to them: server/course/), opens the
LTI tool (server/lti/: its keys and the platforms that may launch it), and starts the janitor (which removes old
finished jobs); at shutdown the grading runs stop where they are (their rows say where), the workers give their
running jobs back to the queue (as soon as a stop signal arrives, with `python -m server`: see `Stopping`), and the
checking processes end. Every request passes the host check and gets the security headers
(server/api/middleware.py); the start-up log warns of a server open to others without an instructor token or a list
of host names.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import threading
import time
from collections.abc import Callable
from contextlib import asynccontextmanager
from datetime import UTC, datetime

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles
from fastapi_offline import FastAPIOffline

from server.api.errors import SafeJSONResponse, install_error_handlers
from server.api.gate import BodyBudget, RequestGate
from server.api.middleware import CrossSiteCheck, HostCheck, SecurityHeaders
from server.api.routes import (
    assignments,
    audit,
    courses,
    dashboard,
    grade,
    jobs,
    lms,
    lti,
    manual,
    own_trees,
    pages,
    reference,
    regrade,
    roster,
    samples,
    scenes,
    similarity,
    stats,
    status,
    submissions,
    tools,
)  # fmt: skip
from server.checkers.pool import CheckPool
from server.core.clients import AddressCaps, StreamCaps
from server.core.db import Tables
from server.core.exits import Stopping
from server.core.migrations import migrate
from server.core.paths import SCENES, WEB
from server.core.security import served_hosts, start_up_warnings
from server.core.settings import Settings, load_settings
from server.core.startup import check_data_dir, lock_data_dir
from server.course.lms import Lms
from server.course.owntrees import TreeCache
from server.course.service import Course
from server.course.similarity import Reports
from server.grading.runs import GradeRuns
from server.jobs import lesson_panels
from server.jobs.janitor import Janitor
from server.jobs.previews import Previews
from server.jobs.service import JobService
from server.jobs.store import JobStore
from server.lti.tool import LtiTool
from server.queue.base import make_queue

log = logging.getLogger("server")

GATE_LOOK_SECONDS, GATE_LOOKS = 0.1, 6000  # TRACER_KERNEL_LOAD_GATE: a look every 0.1 s, 10 minutes at most


@asynccontextmanager
async def lifespan(app: FastAPI):
    settings: Settings = app.state.settings
    for warning in start_up_warnings(settings):
        log.warning(warning)
    lock = app.state.data_lock  # python -m server checked the data directory and took it before serving
    if lock is None:
        check_data_dir(settings.data_dir)
        lock = lock_data_dir(settings.data_dir)
    try:  # before any store opens the database: its schema brought to this release's (a backup first)
        migrate(settings.data_dir, app.state.clock)
    except BaseException:
        lock.close()
        raise
    kernels = app.state.kernels  # set once the render kernels are loaded: this host's workers start then
    with contextlib.ExitStack() as stack:  # what started is stopped, last first, also when a later start fails
        stack.callback(lock.close)
        checks = app.state.checks = CheckPool(settings)
        if not settings.workers:  # else once the kernels' thread (below) has the samples' kernel in Warp's cache
            checks.start()  # scene checks, off the event loop
        stack.callback(checks.shutdown)
        store = JobStore(settings.data_dir)
        # the stores' connections (one per thread that used them) closed last of all: a pool's thread outlives
        # the app, and each connection would keep two files open
        stores: list[JobStore | Tables] = [store]
        stack.callback(lambda: [s.close_connections() for s in stores])
        queue = make_queue(settings, store, app.state.stopping)
        jobs = JobService(settings, store, queue, app.state.stopping)
        app.state.store, app.state.queue, app.state.jobs = store, queue, jobs
        stack.callback(jobs.close)
        grade_runs = app.state.grade_runs = GradeRuns(settings, jobs)
        stores.append(grade_runs.gs)
        queue.start(kernels)  # recovers the jobs a stopped server left, then takes jobs (its workers: once loaded)
        stack.callback(queue.shutdown)
        grade_runs.resume()  # grading runs a stopped server left: on from where their rows say they were
        stack.callback(grade_runs.shutdown)
        course = app.state.course = Course(settings, grade_runs, lambda: app.state.clock())
        course.resume()  # submissions a stopped server accepted but had not handed to their grading run
        app.state.similarity = Reports(course)  # similarity reports, computed in the grading processes
        lti = app.state.lti = LtiTool(settings.data_dir)  # LTI 1.3: keys, platforms, launches (server/lti/)
        stack.callback(lti.close)
        lms = app.state.lms = Lms(course, lti.services, lti.keys, lti.store.platform)  # what a launch opens
        stores += [course.store, lti.store, lms.store]
        lti.handler = lms
        lms.start()  # grades back to the LMS: the rows a stopped server left are posted too
        stack.callback(lms.stop)
        previews = app.state.previews = Previews(settings, jobs, SCENES)
        if settings.previews_ahead:  # the examples' pictures, rendered by the workers before anyone asks
            threading.Thread(target=previews.ahead, name="previews", daemon=True).start()
        if settings.lessons_ahead and jobs.version is not None:  # the lessons' first pictures, answered from these
            threading.Thread(target=lesson_panels.ahead, args=(jobs,), name="lessons-ahead", daemon=True).start()
        # a run waiting for space tries again; the status page reads the size it measured
        janitor = app.state.janitor = Janitor(settings, store, chores=(grade_runs.retry,))
        janitor.start()
        stack.callback(janitor.stop)
        stack.callback(app.state.stopping.set)  # (already set if a signal stopped the server)
        # what start-up made (the modules, Warp, the app) lives as long as the server: out of the collector's
        # sight, so that its full collections walk only what requests make (they took 100-225 ms with 500
        # event streams open, and every request waited for them)
        gc.freeze()
        stack.callback(gc.unfreeze)
        # the kernels in Warp's cache before this host's workers start, so that they only read it: loaded from
        # here on, while the page answers (a cold cache takes a minute or more to compile); a render waits
        if settings.workers:
            args = (kernels, settings, checks.start)
            threading.Thread(target=load_in_background, args=args, name="kernels", daemon=True).start()
        else:
            kernels.set()  # no worker here: the workers elsewhere, and the checking processes, load their own
        yield


def load_in_background(loaded: threading.Event, settings: Settings, start_checkers: Callable[[], None]) -> None:
    """Load the samples' kernel (POST /api/samples) and start the checking processes (they then read it from Warp's
    cache), then load the render kernels and set `loaded`: the workers start. A failure is logged and what waits
    for it starts all the same: each process loads the kernels itself, and says why not."""
    started = time.monotonic()
    try:  # imported here: the modules that define the kernels take seconds to import, after the page answers
        from tracer.tools.pixel_samples import load_kernels as load_sample_kernels

        load_sample_kernels()
    except Exception:
        log.exception("could not load the samples' kernel: the checking processes try on their own")
    start_checkers()
    gate = settings.kernel_load_gate
    if gate is not None:  # the tests' slow machine (TRACER_KERNEL_LOAD_GATE): the workers' start only
        for _ in range(GATE_LOOKS):
            if gate.exists():
                break
            time.sleep(GATE_LOOK_SECONDS)
    try:
        from server.queue.embedded.worker import load_kernels

        load_kernels()
        gc.freeze()  # what they made lives as long as the server, as start-up's does (the lifespan's gc.freeze)
        log.info("render kernels ready (%.1f s): starting the render workers", time.monotonic() - started)
    except Exception:
        log.exception("could not load the render kernels: the render workers try on their own")
    finally:
        loaded.set()


def utc_now() -> datetime:
    return datetime.now(UTC)


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or load_settings()
    app = FastAPIOffline(  # /docs: Swagger UI with its scripts served by us, so it works offline
        title="Ray tracing for teaching",
        version="0.1.0",
        lifespan=lifespan,
        default_response_class=SafeJSONResponse,
        description="Submit scenes, watch them render progressively, inspect the ray tree of any pixel. "
        'Every error answer is `{"errors": [{"path", "message"}]}` with the JSON path of the offending field.',
        static_url="/api-docs-assets",
        swagger_ui_parameters={"validatorUrl": None},  # no badge fetched from the Swagger validator's site
        redoc_url=None,  # ReDoc's bundle still fetches its maker's logo from a CDN: /docs alone, fully offline
    )
    app.state.settings = settings
    app.state.store = app.state.queue = app.state.jobs = app.state.grade_runs = app.state.checks = None
    app.state.course = app.state.lti = app.state.lms = app.state.similarity = app.state.janitor = None
    app.state.clock = utc_now  # the API's time (deadlines, a submission's time): tests set another
    app.state.tree_cache = TreeCache()  # the reference's trees that own tracers' logs are compared with
    app.state.caps = AddressCaps(settings)  # what one address may do without a known identity (in memory)
    app.state.streams = StreamCaps(settings, app.state.caps)  # event streams open per token and per address
    app.state.data_lock = None  # the data directory's lock, when the command line took it (server/__main__.py)
    # set by `python -m server`'s signal handler the moment SIGTERM or Ctrl-C arrives (before uvicorn waits for the
    # open connections), else at the lifespan's end: the workers give their jobs back, event streams end
    app.state.stopping = Stopping()
    app.state.kernels = threading.Event()  # set once the render kernels are loaded (the lifespan)
    install_error_handlers(app)
    upload = (int(settings.max_class_bytes) + settings.max_body_bytes, "TRACER_MAX_CLASS_BYTES + TRACER_MAX_BODY_BYTES")
    budget = BodyBudget(int(settings.body_budget_bytes), settings.body_budget_wait)  # large bodies held at once
    app.add_middleware(
        RequestGate, max_bytes=settings.max_body_bytes, max_depth=settings.max_json_depth,
        streamed={grade.UPLOAD: upload}, body_timeout=settings.body_timeout, budget=budget,
        larger=[(own_trees.TREES_PATH, int(settings.max_tree_log_bytes), "TRACER_MAX_TREE_LOG_BYTES")],
    )  # fmt: skip
    app.add_middleware(CrossSiteCheck, served=served_hosts(settings))  # no page of another site changes anything
    app.add_middleware(HostCheck, served=served_hosts(settings))  # a foreign Host gets nothing but a 400
    # the outermost: every answer has its policy, nosniff, no framing but by the registered LTI platforms
    app.add_middleware(SecurityHeaders, frame_ancestors=lambda: app.state.lti.origins() if app.state.lti else [])
    app.include_router(jobs.router)
    app.include_router(tools.router)
    app.include_router(samples.router)
    app.include_router(scenes.router)
    app.include_router(grade.router)
    # a student tracer's tree log, compared (docs/own-tracer.md): before submissions' GET .../{sid}/{name} (a
    # submission's picture), which would take GET .../{sid}/trees for a picture named "trees"
    app.include_router(own_trees.router)
    app.include_router(similarity.router)  # before submissions.py, as own_trees
    app.include_router(stats.router)  # before submissions.py, as similarity
    app.include_router(manual.router)  # before submissions.py, as similarity
    app.include_router(regrade.router)  # before submissions.py, as similarity
    app.include_router(assignments.router)  # /api/assignments: the assignment, then its roster, submissions, class
    app.include_router(roster.router)
    app.include_router(submissions.router)
    app.include_router(dashboard.router)
    app.include_router(audit.router)  # /api/courses/{cid}/audit
    app.include_router(courses.router)
    app.include_router(reference.router)  # docs/*.md as HTML at /reference/
    app.include_router(lti.router)  # LTI 1.3: /lti/login, /lti/launch, /lti/jwks, /api/lti/platforms
    app.include_router(lms.router)  # the course's side of LTI: /lti/pick, an LMS course's roster, grades back
    app.include_router(status.router)  # /status and /api/status: the operator's page (admin)
    app.include_router(pages.router)  # /assignments/{id} and /course: the course's pages of web/
    app.mount("/", StaticFiles(directory=WEB, html=True), name="web")
    return app
