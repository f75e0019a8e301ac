"""The job service: the one place that uses the job store and the job queue together.

Every caller that makes a job submits it here (the routes of renders and ray trees, the examples'
previews, grading runs): the store records it queued, then the queue is told. Cancels, the waits for
a job's end, the render estimate and the public view (a queued job's place and its expected wait)
live here too, and so do a job's changes: one watcher thread (`JobWatch`) reads the rows of every job
someone follows in one query and wakes the followers whose job changed, so no event stream and no
waiting request polls the store on its own.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Iterable
from contextlib import contextmanager
from typing import TYPE_CHECKING, Generic, TypeVar

import anyio

from server.core.errors import ClientGone, Invalid, TookTooLong, TooMany, Unavailable
from server.core.settings import Settings
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobKind, JobStatus, Lane
from server.jobs.placing import Placed, place
from server.jobs.results import DEVICE, link_files, renderer_version, result_key
from server.jobs.rows import JobRow
from server.jobs.store import JobStore, QueueFull
from server.jobs.views import JobPublic, QueuePlace

if TYPE_CHECKING:  # the queue's backends import the jobs package; the service only calls the interface
    from server.queue.base import JobQueue

TICK = 0.1  # seconds between two looks at the followed jobs' rows
URGENT_TICK = 0.01  # ... while someone waits for a short job to end (a ray tree: a student clicked a pixel)
PLACE_EVERY = 1.0  # seconds between two wakes of a queued job's followers (its place moves with other jobs)
PROGRESS_EVERY = 0.5  # seconds between two wakes of a job's followers for its progress alone (the latest is kept)
PROGRESS_FIELDS = frozenset({"samples_done", "samples_total", "passes_done", "spp_done", "rays", "solve"})
CAPACITY_SECONDS = 1.0  # how long the queue's count of workers per lane is kept (Redis lists them from Redis)
KEEPALIVE = 15.0  # seconds of quiet after which a follower is handed None (an SSE comment keeps the line open;
# a submission's stream, server/api/routes/submissions.py, keeps the same)
VIEWS_KEPT = 4096  # views of followed jobs' rows kept for their other followers (a class's jobs, and more)
ACTIVE_RETRY = 10  # seconds a client past its share of the workers is told to wait (Retry-After)
R = TypeVar("R")  # what `wake` hands a follower: a job's row (JobWatch); a course's submission follower, {"id": ...}
WAKE = 1.0  # seconds a follower waits before it looks again whether its client or the server is going


class Follower(Generic[R]):
    """One follower of one job (an event stream, a waiting request): woken in its event loop when the job's
    row changes; `row` is the latest the watcher read. Plain futures and timer handles of its loop, no cancel
    scope: a class's 500 streams woken five times a second wait 2 500 times a second (anyio's cancel scopes
    cost the loop more than the streams' writes)."""

    def __init__(self, job_id: str, urgent: bool):
        self.job_id, self.urgent = job_id, urgent
        self.loop = asyncio.get_running_loop()
        self.pending = False  # woken, and not yet handed the row (in its loop)
        self._waiter: asyncio.Future | None = None  # what `changed` awaits
        self.row: R | None = None
        self.woken = 0.0  # monotonic time of the last wake (a queued job's followers are woken every PLACE_EVERY)

    def wake(self, row: R | None, now: float | None = None) -> None:
        """From the watcher's thread: its latest `row` (at `now`, monotonic); `wake_all` then sets it going."""
        self.row, self.woken = row, time.monotonic() if now is None else now

    def _set(self) -> None:
        """In its loop: woken."""
        self.pending = True
        _resolve(self._waiter)

    async def changed(self, timeout: float) -> R | None:
        """The job's row once it changed, or None after `timeout` seconds without a change."""
        if not self.pending:
            waiter = self._waiter = self.loop.create_future()
            timer = self.loop.call_later(timeout, _resolve, waiter)
            try:
                await waiter
            finally:
                timer.cancel()
                self._waiter = None
        if not self.pending:
            return None
        self.pending = False
        return self.row


def _resolve(waiter: asyncio.Future | None) -> None:
    if waiter is not None and not waiter.done():
        waiter.set_result(None)


def wake_all(followers: list[Follower]) -> None:
    """Set the followers going, each in its event loop: one call into each loop for all its followers (a
    class's 500 streams woken by one change cost their loop one wake-up, not 500)."""
    by_loop: dict[asyncio.AbstractEventLoop, list[Follower]] = {}
    for f in followers:
        by_loop.setdefault(f.loop, []).append(f)
    for loop, woken in by_loop.items():
        loop.call_soon_threadsafe(_set_all, woken)


def _set_all(followers: list[Follower]) -> None:
    for f in followers:
        f._set()


class JobWatch:
    """One thread for all followers: while anyone follows a job, it reads the followed rows (without their
    scenes) in one query every TICK seconds (URGENT_TICK while an urgent follower waits), and wakes the
    followers of each row that changed, and of each queued job every PLACE_EVERY seconds. A change of progress
    alone wakes them at most every PROGRESS_EVERY seconds, with the latest: a render writes its progress five
    times a second, and each wake of a class's 250 streams on one job is 250 writes in a row on the event loop,
    which every other request waits behind. A change of anything else (its status, a new image, its try) wakes
    them at once."""

    def __init__(self, store: JobStore, stopping: Callable[[], bool], clock: Callable[[], float] = time.monotonic):
        self.store, self.stopping, self.clock = store, stopping, clock
        self._lock = threading.Lock()
        self._followers: dict[str, set[Follower[JobRow]]] = {}
        self._sent: dict[str, tuple[JobRow | None, float]] = {}  # job id -> the row its followers were woken with, when
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False

    @contextmanager
    def follow(self, job_id: str, urgent: bool = False):
        follower = Follower[JobRow](job_id, urgent)
        with self._lock:
            self._followers.setdefault(job_id, set()).add(follower)
            if self._thread is None and not self._closed:
                self._thread = threading.Thread(target=self._loop, name="job-watch", daemon=True)
                self._thread.start()
        self._wake.set()
        try:
            yield follower
        finally:
            with self._lock:
                mine = self._followers.get(job_id)
                if mine is not None:
                    mine.discard(follower)
                    if not mine:
                        del self._followers[job_id]
                        self._sent.pop(job_id, None)

    def followers(self) -> int:
        """How many follow a job now (event streams, waiting requests)."""
        with self._lock:
            return sum(len(fs) for fs in self._followers.values())

    def close(self) -> None:
        self._closed = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def _loop(self) -> None:
        while not self._closed:
            with self._lock:
                followers = {k: set(v) for k, v in self._followers.items()}
            if not followers:
                self._wake.wait(1.0)
                self._wake.clear()
                continue
            try:
                self._round(followers)
            except Exception:  # a locked or full database: the next round tries again
                pass
            urgent = any(f.urgent for fs in followers.values() for f in fs)
            self._wake.wait(URGENT_TICK if urgent else TICK)
            self._wake.clear()

    def _round(self, followers: dict[str, set[Follower[JobRow]]]) -> None:
        rows = self.store.rows(followers)
        now, stopping = self.clock(), self.stopping()
        woken = []
        for job_id, fs in followers.items():
            row = rows.get(job_id)
            sent, at = self._sent.get(job_id, (False, 0.0))
            changed = sent != row and (stopping or now - at >= PROGRESS_EVERY or not _progress_only(sent, row))
            if changed:
                self._sent[job_id] = (row, now)
            for f in fs:
                queued = row is not None and row["status"] == JobStatus.queued
                if changed or stopping or f.row is None or (queued and now - f.woken >= PLACE_EVERY):
                    f.wake(row, now)
                    woken.append(f)
        wake_all(woken)


def _progress_only(before: JobRow | None | bool, after: JobRow | None) -> bool:
    """Whether two different rows of a job differ in its progress fields alone."""
    if not isinstance(before, dict) or after is None or before.keys() != after.keys():
        return False
    return all(before[k] == after[k] for k in after if k not in PROGRESS_FIELDS)


class JobService:
    """Submit, cancel, wait for, estimate and show jobs (the routes, previews and grading all come here)."""

    def __init__(self, settings: Settings, store: JobStore, queue: JobQueue, stopping: Callable[[], bool]):
        self.settings, self.store, self.queue, self.stopping = settings, store, queue, stopping
        self.watch = JobWatch(store, stopping)
        self._capacity: dict[Lane, tuple[float, int]] = {}
        self._views: dict[str, tuple] = {}  # job id -> (the row the watcher read, its view or the view coming)
        self.version = renderer_version() if settings.answer_again else None  # what besides a scene makes pixels

    def close(self) -> None:
        self.watch.close()

    # -- submit and cancel ----------------------------------------------------------------------

    def submit(self, scene: str, *, name: str | None, width: int, height: int, spp: int, **fields) -> JobRow:
        """Record a queued job of `scene` (JSON text) and get it rendered; its row. `fields` as the store's
        `create` takes them; the time limit and the queue's size default to the settings'. Raises QueueFull."""
        fields.setdefault("max_seconds", self.settings.max_job_seconds)
        fields.setdefault("max_queued", self.settings.max_queued_jobs)
        fields.setdefault("warnings", [])
        fields.setdefault("priority", 0)
        row = self.store.create(scene, name=name, width=width, height=height, spp=spp, **fields)
        self.queue.submitted(row)
        return row

    def submit_checked(self, found: dict, **fields) -> JobRow:
        """A client's job of a scene checked in a checking process (its summary: server/checkers/tasks.py);
        a render whose result a done render has is done at once (`answer_again`); 429 when the queue, or the
        owner's share of it, is full."""
        fields.setdefault("max_queued_owner", self.settings.max_queued_per_token)
        name = fields.pop("name", found["name"])
        if self.version is not None and fields.get("kind", JobKind.render) == JobKind.render:
            fields["result_key"] = result_key(found["text"], self.version)
            answered = self.answer_again(fields["result_key"], found["text"], name=name, **fields)
            if answered is not None:
                return answered
        try:
            return self.submit(found["text"], name=name, width=found["width"],
                               height=found["height"], spp=found["spp"], **fields)  # fmt: skip
        except QueueFull as full:
            if full.args[1:] == ("owner",):
                message = (
                    f"you already have {full.args[0]} jobs waiting (TRACER_MAX_QUEUED_PER_TOKEN): wait for one to "
                    "start, or cancel one"
                )
            elif full.args[1:] == ("active",):
                message = (
                    f"you already have {full.args[0]} renders waiting or running, your share of the workers "
                    "(TRACER_MAX_ACTIVE_JOBS_PER_TOKEN): wait for one to end, or cancel one"
                )
                raise TooMany(message, retry_after=ACTIVE_RETRY) from None
            else:
                message = f"the queue is full ({full.args[0]} jobs waiting, TRACER_MAX_QUEUED_JOBS); try again later"
            raise TooMany(message, retry_after=5) from None

    def answer_again(self, key: str, scene: str, *, name: str | None, **fields) -> JobRow | None:
        """A new job of `scene`, done, with the files of the latest done render of result `key`
        (server/jobs/results.py), for the fields' owner, lane and priority; None when there is none."""
        source = self.store.done_result(key, DEVICE)
        if source is None:
            return None

        def link(job_id: str) -> bool:
            return link_files(self.store.job_dir(source["id"]), self.store.job_dir(job_id), (JobFile.snapshot.value,))

        return self.store.create_answered(
            source, link, scene_json=scene, name=name, priority=fields.get("priority", 0),
            warnings=fields.get("warnings", []), lane=fields.get("lane", Lane.interactive),
            estimate=fields.get("estimate"), owner=fields.get("owner"),
        )  # fmt: skip

    def cancel(self, job_id: str) -> JobRow | None:
        """Cancel a queued job, or ask a running one to stop (the store decides, in one transaction), and
        tell the queue; the row after."""
        row = self.store.cancel(job_id)
        if row is not None:
            self.queue.cancelled(row)
        return row

    # -- the estimate ---------------------------------------------------------------------------

    def estimate(self, found: dict) -> float:
        """The render's estimated seconds on one worker (tracer/rendering/estimate.py, in the scene's summary; scaled by
        how long finished renders took against their estimates); 422 when past the per-job limit, so it is
        never accepted to fail later (at render.radiosity when the radiosity solve alone is past it)."""
        pace = self.store.pace()
        seconds, limit = found["seconds"] * pace, self.settings.max_job_seconds
        if seconds > limit:
            solve = found["solve_seconds"] * pace
            if solve > limit:
                message = (
                    f"its radiosity solve would take about {solve:.0f} s here, past the limit of {limit:g} s per "
                    "job (TRACER_MAX_JOB_SECONDS): use a larger patch_size, fewer rays or a larger threshold"
                )
                raise Invalid([{"path": "render.radiosity", "message": message}])
            work = f"{found['width']} x {found['height']} pixels x {found['spp']} samples"
            message = (
                f"this render would take about {seconds:.0f} s here ({work}, {found['integrator']}), past the "
                f"limit of {limit:g} s per job (TRACER_MAX_JOB_SECONDS): use fewer pixels or samples"
            )
            raise Invalid([{"path": "sampler.spp", "message": message}])
        return round(seconds, 3)

    def place(self, seconds: float, lane: Lane | None, priority: int, staff: bool) -> Placed:
        """A render's lane and priority by who asks (server/jobs/placing.py), with warnings for what was lowered."""
        return place(seconds, self.settings.interactive_seconds, lane, priority, staff)

    def solve_estimate(self, found: dict) -> float:
        """The radiosity solve's estimated seconds (a ray tree's worker refuses it past its limit, unless kept)."""
        return round(found["solve_seconds"] * self.store.pace(), 3)

    # -- the public view ------------------------------------------------------------------------

    def capacity(self, lane: Lane) -> int:
        """Workers that take jobs of `lane`, kept CAPACITY_SECONDS (the Redis backend reads them from Redis)."""
        now = time.monotonic()
        kept = self._capacity.get(lane)
        if kept is None or now - kept[0] > CAPACITY_SECONDS:
            kept = self._capacity[lane] = (now, self.queue.capacity(lane))
        return kept[1]

    def public(self, row: JobRow, now: float | None = None) -> JobPublic:
        """The job as the API shows it; a queued one with its place in the queue and its expected wait."""
        job = JobPublic.from_row(row, now)
        if job.status is JobStatus.queued:
            lane = Lane(row["lane"])
            place = self.store.place(row)
            workers = self.capacity(lane)
            wait = None
            if workers > 0:
                wait = round((place["ahead_seconds"] + place["running_seconds"]) / workers, 2)
            job.queue = QueuePlace(
                lane=lane, position=place["ahead"] + 1, ahead=place["ahead"], running=place["running"],
                workers=workers, expected_wait=wait,
            )  # fmt: skip
        return job

    async def _view(self, row: JobRow) -> JobPublic:
        """The row's public view. The watcher hands one row to all of a job's followers: its view is made once
        for them all (500 streams of a class on two jobs made 500 views, and queries, per change)."""
        made = self._views.get(row["id"])
        if made is None or made[0] is not row:
            if row["status"] == JobStatus.queued:  # its place is a query, in a thread: one task for all who wait
                view = asyncio.ensure_future(anyio.to_thread.run_sync(self.public, row))
            else:
                view = self.public(row)
            if len(self._views) >= VIEWS_KEPT:
                self._views.clear()
            made = self._views[row["id"]] = (row, view)
        view = made[1]
        return await asyncio.shield(view) if isinstance(view, asyncio.Future) else view

    # -- following and waiting ------------------------------------------------------------------

    async def follow(self, job_id: str) -> AsyncIterator[JobPublic | None]:
        """The job's public view now and each time it changes, until it has ended (the last one yielded is
        finished) or the server stops; None after KEEPALIVE quiet seconds. It never asks whether its client left:
        the caller ends it then (an event stream's response cancels it: see server/api/routes/jobs.py)."""
        with self.watch.follow(job_id) as follower:
            row = await anyio.to_thread.run_sync(self.store.get, job_id)
            quiet = time.monotonic()
            while row is not None:
                job = await self._view(row)
                yield job
                if job.status.finished:
                    return
                row = None
                while row is None:
                    row = await follower.changed(WAKE)
                    if self.stopping():
                        return  # a stopping server ends its streams (the client reconnects to the next one)
                    if row is None and time.monotonic() - quiet > KEEPALIVE:
                        quiet = time.monotonic()
                        yield None
                quiet = time.monotonic()

    async def ended(self, job_id: str, seconds: float, gone: Callable[[], Awaitable[bool]]) -> JobRow | None:
        """Wait for a short job to end (a ray tree): its finished row; None when `seconds` passed first, the
        server is stopping, or `gone()` says the client left (see `self.stopping()` for which)."""
        deadline = time.monotonic() + seconds
        with self.watch.follow(job_id, urgent=True) as follower:
            row = await anyio.to_thread.run_sync(self.store.get, job_id)
            while row is None or not JobStatus(row["status"]).finished:
                left = deadline - time.monotonic()
                if left <= 0 or self.stopping() or await gone():
                    return None
                row = await follower.changed(min(WAKE, left)) or row
            return row

    async def raytree(
        self,
        found: dict,
        pixel: tuple[int, int, int],
        *,
        priority: int,
        owner: str | None,
        name: str,
        gone: Callable[[], Awaitable[bool]],
        queued: Callable[[JobRow], None] = lambda row: None,
    ) -> dict:
        """One pixel sample's ray tree (`pixel`: x, y, sample) of a scene checked in a checking process: a short
        job of the interactive lane, waited for (`queued` hears of its row first, in the submitting thread). Its
        tree; or a domain error (server/core/errors.py): Invalid at x, y or sample outside the film or its samples
        (nothing queued), or with the errors the job ended with; Unavailable when no worker takes interactive work,
        the server stops, or the job failed otherwise; TookTooLong past TRACER_MAX_RAYTREE_SECONDS; ClientGone
        when the client went away."""
        from tracer.rendering.raytree import pixel_sample_errors  # here: its module defines the kernels (seconds)

        x, y, sample = pixel
        limit = self.settings.max_raytree_seconds
        errors = pixel_sample_errors(x, y, sample, found["width"], found["height"], found["samples"])
        if errors:  # before anything is queued: a job that could only fail is never made
            raise Invalid(errors)
        if self.capacity(Lane.interactive) == 0:
            raise Unavailable("no render worker takes interactive work: start one (TRACER_WORKERS, or a worker host)")

        def submit() -> JobRow:
            params = {"x": x, "y": y, "sample": sample, "solve_seconds": self.solve_estimate(found)}
            row = self.submit_checked(
                found, kind=JobKind.raytree, lane=Lane.interactive, priority=priority, params=params,
                max_seconds=limit, samples_total=1, owner=owner, name=name[:200],
            )  # fmt: skip
            queued(row)
            return row

        row = await anyio.to_thread.run_sync(submit)
        ended = await self.ended(row["id"], limit + 10, gone)
        if ended is None:
            await anyio.to_thread.run_sync(self.cancel, row["id"])
            if self.stopping():
                raise Unavailable("the server is stopping: ask again once it is back", retry_after=5)
            if await gone():
                raise ClientGone("the client went away")
            raise TookTooLong(f"the ray tree took longer than {limit:g} s")
        if ended["status"] == JobStatus.done:
            tree = self.store.job_file(ended["id"], JobFile.raytree)
            return json.loads(await anyio.to_thread.run_sync(tree.read_text))
        errors = json.loads(ended["errors"] or "[]")
        if errors:
            raise Invalid(errors)
        raise Unavailable(ended["error"] or f"the ray tree's job was {ended['status']}")

    def states(self, ids: Iterable[str]) -> dict[str, dict]:
        """What a grading run needs of its render jobs (status, error, spp_done, started_at, finished_at), for
        those that still exist, in one query per 500 ids: the run looks at them between its own tasks."""
        return self.store.states(ids)
