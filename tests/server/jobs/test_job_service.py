"""The job service (server/jobs/service.py): every job made through it, and one watcher that wakes the
followers of the jobs that changed, reading every followed row in one query (no stream polls the store)."""

from __future__ import annotations

import asyncio
import contextlib
import json

from server.core.settings import Settings
from server.jobs.lifecycle import JobStatus, Lane
from server.jobs.service import JobService, JobWatch
from server.jobs.store import JobStore


class Recording:
    """The queue's interface as far as these tests need it: what was handed to it, and its workers."""

    def __init__(self, workers: int = 1):
        self.submitted_rows, self.cancelled_rows, self.asked, self.workers = [], [], 0, workers

    def submitted(self, row: dict) -> None:
        self.submitted_rows.append(row)

    def cancelled(self, row: dict) -> None:
        self.cancelled_rows.append(row)

    def capacity(self, lane) -> int:
        self.asked += 1
        return self.workers


class CountingStore(JobStore):
    """A real store on disk that counts the watcher's reads."""

    reads = 0

    def rows(self, ids):
        self.reads += 1
        return super().rows(ids)


def service(tmp_path, workers: int = 1) -> tuple[JobService, Recording]:
    queue = Recording(workers)
    settings = Settings(data_dir=tmp_path)
    return JobService(settings, CountingStore(tmp_path), queue, lambda: False), queue


def submit(jobs: JobService, **fields) -> dict:
    return jobs.submit(json.dumps({"name": "x"}), name="x", width=4, height=3, spp=1, **fields)


def test_job_service_submits_to_the_store_then_the_queue(tmp_path):
    jobs, queue = service(tmp_path)
    row = submit(jobs, lane=Lane.batch)
    assert [r["id"] for r in queue.submitted_rows] == [row["id"]]
    assert jobs.store.get(row["id"])["status"] == JobStatus.queued
    assert row["max_seconds"] == 600.0
    cancelled = jobs.cancel(row["id"])
    assert cancelled["status"] == JobStatus.cancelled
    assert [r["id"] for r in queue.cancelled_rows] == [row["id"]]


def test_job_service_keeps_the_queue_s_worker_count_a_second(tmp_path):
    """A queued job's view asks the queue how many workers take its lane (the Redis backend lists them from
    Redis): 100 views ask it once."""
    jobs, queue = service(tmp_path, workers=2)
    row = submit(jobs)
    views = [jobs.public(jobs.store.get(row["id"])) for _ in range(100)]
    assert queue.asked == 1
    assert {v.queue.workers for v in views} == {2}


def test_job_service_watch_reads_every_followed_job_in_one_query_and_wakes_only_the_changed(tmp_path):
    """50 followers (event streams) of 50 jobs: one job changes, its follower alone is woken, and the store
    is read once per look for all of them (a few looks in 0.35 s, not 50 per look)."""
    jobs, _ = service(tmp_path)
    rows = [submit(jobs) for _ in range(50)]
    store = jobs.store
    watch = JobWatch(store, lambda: False)

    async def run() -> tuple[int, list[bool]]:
        with contextlib.ExitStack() as stack:
            followers = [stack.enter_context(watch.follow(r["id"])) for r in rows]
            first = [await f.changed(5.0) for f in followers]  # each is handed its row once
            assert [r["id"] for r in first] == [r["id"] for r in rows]
            reads = store.reads
            store.cancel(rows[7]["id"])  # one job changes
            await asyncio.sleep(0.35)
            return store.reads - reads, [f.pending for f in followers]

    try:
        reads, woken = asyncio.run(run())
    finally:
        watch.close()
    assert woken == [i == 7 for i in range(50)]
    assert 1 <= reads <= 6, reads


def test_job_service_one_view_of_a_row_for_all_its_followers(tmp_path):
    """The watcher hands one row to all of a job's followers: 100 streams woken at once by a queued job's row
    (whose view, with its place in the queue, is made in a thread) and by a running one's make one view each,
    and a new row of the job a new view."""
    jobs, _ = service(tmp_path)
    queued, running = submit(jobs), submit(jobs)
    made: list[str] = []
    public = jobs.public

    def counted(row: dict):
        made.append(row["id"])
        return public(row)

    jobs.public = counted
    queued_row = jobs.store.get(queued["id"])
    running_row = {**jobs.store.get(running["id"]), "status": JobStatus.running}

    async def run() -> list:
        rows = [queued_row] * 100 + [running_row] * 100
        return await asyncio.gather(*(jobs._view(row) for row in rows))

    views = asyncio.run(run())
    assert sorted(made) == sorted([queued["id"], running["id"]])
    assert len({id(v) for v in views}) == 2 and views[0].id == queued["id"] and views[-1].id == running["id"]
    asyncio.run(jobs._view(dict(queued_row)))  # a row read again (the job changed): its own view
    assert made.count(queued["id"]) == 2


def test_job_service_one_change_wakes_all_its_followers_in_one_call_into_their_loop(tmp_path):
    """500 event streams on one job: the change of its row wakes all of them with one call into their event loop
    (one wake-up of the loop from the watcher's thread, not 500), and each is handed the new row."""
    jobs, _ = service(tmp_path)
    row = submit(jobs)
    watch = JobWatch(jobs.store, lambda: False)

    async def run() -> list:
        loop = asyncio.get_running_loop()
        calls, threadsafe = [], loop.call_soon_threadsafe
        loop.call_soon_threadsafe = lambda cb, *args, **kw: calls.append(cb) or threadsafe(cb, *args, **kw)
        with contextlib.ExitStack() as stack:
            followers = [stack.enter_context(watch.follow(row["id"])) for _ in range(500)]
            for f in followers:
                assert (await f.changed(5.0))["status"] == JobStatus.queued
            before = len(calls)
            jobs.store.cancel(row["id"])
            for f in followers:
                assert (await f.changed(5.0))["status"] == JobStatus.cancelled
            return calls[before:]

    try:
        calls = asyncio.run(run())
    finally:
        watch.close()
    assert len(calls) == 1, calls


def test_job_service_a_view_s_event_texts_are_made_once_for_all_its_streams(tmp_path):
    """The event stream's texts of one view (server/api/routes/jobs.py): its followers share the view, and the
    second stream to send it gets the very texts the first made; another view of the row its own."""
    from server.api.routes.jobs import _texts

    jobs, _ = service(tmp_path)
    row = submit(jobs)
    view = jobs.public(jobs.store.get(row["id"]))
    first = _texts(view, row["id"])
    assert _texts(view, row["id"]) is first
    assert first[1].startswith("event: progress\ndata: {")
    assert first[2] is None
    assert first[3] is None
    jobs.store.cancel(row["id"])
    ended = _texts(jobs.public(jobs.store.get(row["id"])), row["id"])
    assert ended is not first
    assert ended[3].startswith("event: end\ndata: {")
    assert '"cancelled"' in ended[3]


def test_job_service_a_follower_is_handed_a_running_render_s_changes_to_its_end(tmp_path):
    """A running render's follower (an event stream) is handed its changes as they come, and the finished view
    last, where following ends. It never asks whether its client left (asking once a second from each of a
    class's 500 streams took a tenth of the event loop's time; the stream's response cancels it instead)."""
    from server.jobs import service as service_module

    jobs, _ = service(tmp_path)
    row = submit(jobs)
    assert jobs.store.claim(pid=7)["id"] == row["id"]
    seen = []

    async def run() -> None:
        async def changes() -> None:
            for k in range(1, 21):
                await asyncio.to_thread(jobs.store.progress, row["id"], 7, samples_done=k)
                await asyncio.sleep(0.03)
            await asyncio.to_thread(jobs.store.finish, row["id"], 7, JobStatus.done)

        task = asyncio.ensure_future(changes())
        async for view in jobs.follow(row["id"]):
            seen.append((view.status, view.progress.samples_done))
        await task

    service_module.PROGRESS_EVERY, every = 0.0, service_module.PROGRESS_EVERY  # each change of progress its wake
    try:
        asyncio.run(run())
    finally:
        service_module.PROGRESS_EVERY = every
        jobs.close()
    assert len(set(seen)) >= 5 and seen[-1] == (JobStatus.done, 20), seen  # the watcher looks every TICK


def test_job_service_progress_alone_wakes_a_job_s_followers_at_most_every_progress_every(tmp_path):
    """A render writes its progress five times a second; each wake of a class's streams on the job is a write
    to each of them in a row on the event loop. Progress alone wakes the followers at most every PROGRESS_EVERY
    seconds (of the watcher's clock), handing them the latest; a change of status wakes them at once. Failed
    before with a wake at each change."""
    from server.jobs.service import PROGRESS_EVERY, Follower

    jobs, _ = service(tmp_path)
    row = submit(jobs)
    assert jobs.store.claim(pid=7)["id"] == row["id"]
    now = [100.0]
    watch = JobWatch(jobs.store, lambda: False, clock=lambda: now[0])

    async def run() -> list:
        follower = Follower(row["id"], urgent=False)
        handed = []

        def look(at: float, **progress) -> None:  # the job writes its progress, then the watcher looks at `at`
            if progress:
                assert jobs.store.progress(row["id"], 7, **progress)
            now[0] = at
            before = follower.row
            watch._round({row["id"]: {follower}})
            handed.append(None if follower.row is before else (follower.row["status"], follower.row["samples_done"]))

        look(100.0)  # a new follower: handed the row
        look(100.1, samples_done=1)  # progress within PROGRESS_EVERY of the last wake: not yet
        look(100.0 + PROGRESS_EVERY / 2, samples_done=2)
        look(100.0 + PROGRESS_EVERY, samples_done=3)  # due: the latest
        look(100.0 + PROGRESS_EVERY + 0.01, samples_done=4)
        jobs.store.finish(row["id"], 7, JobStatus.done)
        look(100.0 + PROGRESS_EVERY + 0.02)  # a new status: at once, with the latest progress
        look(100.0 + PROGRESS_EVERY + 0.03)  # nothing new
        return handed

    try:
        handed = asyncio.run(run())
    finally:
        watch.close()
    assert handed == [("running", 0), None, None, ("running", 3), None, ("done", 4), None], handed
