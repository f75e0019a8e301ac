"""The embedded backend's render worker: a process on the API's host that takes jobs from the SQLite
queue and renders them (server/queue/render_try.py), reporting straight into the job store.

Started by the server (server/queue/embedded/pool.py), forked from its forkserver (server/core/children.py: the
imports done there once), it loads the Warp kernels once, then loops: claim the next job (priority, then age;
an idle worker sleeps until the server signals a submission, or `poll_interval` at most) and render it. Only plain
data crosses the process boundary: the job row in SQLite, the settings as a dict, and the image files.

A full disk (the job store or a job's files cannot be written) never ends a worker: the job it renders
fails with that reason (recorded as soon as the store can be written again), and it takes the next job
once there is space; the API answers new jobs with 507 meanwhile.

`python -m server.worker --redis URL` is the other backend's worker host (server/queue/redis/host.py).
"""

from __future__ import annotations

import logging
import os
import signal
import time

from server.core.exits import exit_now
from server.core.files import is_disk_full
from server.core.settings import Settings
from server.jobs.lifecycle import LANES, Stop, TryEnd
from server.jobs.rows import JobRow
from server.jobs.store import JobStore
from server.queue.channel import StoreChannel
from server.queue.embedded.wakeup import WorkerEnd
from server.queue.render_try import Try, disk_full_error
from tracer.assets import import_mesh_reader

log = logging.getLogger(__name__)

DISK_FULL_PAUSE = 2.0  # seconds between two tries to write the job store while the disk is full


def worker_main(settings_data: dict, conn, lanes: list[str] | None = None) -> None:
    """Entry point of a worker process (forked from the server's forkserver: nothing of the server's state);
    `conn` is its end of the server's line (server/queue/embedded/wakeup.py): wakes come in, "ready" goes out,
    end-of-file means stop."""
    # Ctrl-C, `kill -- -PGID` and a service manager signal the whole group: the server stops us (closing our
    # line: we give our job back), never a signal, which would end the job's try as a crash
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    line = WorkerEnd(conn)
    settings = Settings(**settings_data)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s[%(process)d]: %(message)s")
    try:
        os.nice(settings.worker_nice)
    except OSError:
        pass
    load_kernels()
    if settings.preload_mesh_reader:
        import_mesh_reader()  # else a student's first job with a mesh file waits for it
    line.ready()
    Worker(settings, JobStore(settings.data_dir), line.stopping, lanes=tuple(lanes or LANES)).loop(line.wait)
    exit_now()  # its job is back in the queue: seconds of the interpreter's teardown would only delay the server


def load_kernels() -> None:
    """Compile (or load from Warp's disk cache) the render kernels, once per process."""
    from tracer.rendering.progressive import load_kernels as load

    load("cpu")


class Worker:
    """Claims and renders jobs; `stopping()` says the process should give its job back and exit."""

    def __init__(self, settings: Settings, store: JobStore, stopping, pid: int | None = None, lanes: tuple = LANES):
        self.settings, self.store, self.stopping = settings, store, stopping
        self.wait = time.sleep  # how it waits: `loop` is given the line's wait (a wake or a stop ends it early)
        self.pid = pid or os.getpid()
        self.lanes = lanes
        from tracer.radiosity import SolutionCache

        self.cache = SolutionCache(settings.cache_dir or settings.data_dir / "cache" / "radiosity")

    def loop(self, wait) -> None:
        log.info("render worker %d ready", self.pid)
        self.wait = wait
        while not self.stopping():
            try:
                job = self.store.claim(self.pid, self.lanes)
            except Exception as exc:
                if not is_disk_full(exc):
                    raise
                self._disk_full(f"cannot take a job ({exc})")
                continue
            if job is None:
                wait(self.settings.poll_interval)
                continue
            self.run(job)
        log.info("render worker %d stopping", self.pid)

    def run(self, job: JobRow) -> TryEnd | Stop:
        """One try of a claimed job, reported into the store; how it ended (see rendering.Try.run)."""
        log.info("job %s: rendering (try %d)", job["id"], job["attempts"])
        channel = StoreChannel(self.store, job, self.pid)
        settings = self.settings
        try:
            return Try(
                job, channel, settings.limits, settings.threads_per_worker(), settings.preview_interval,
                self.stopping, cache=self.cache, snapshot_interval=settings.snapshot_interval,
            ).run()  # fmt: skip
        except Exception as exc:  # the try could not even record its end: the disk is full
            if not is_disk_full(exc):
                raise
            self._fail_when_possible(job, disk_full_error(exc))
            return TryEnd.failed

    def _fail_when_possible(self, job: JobRow, error: str) -> None:
        """Fail the job with `error` as soon as the store can be written again. The worker waits rather than
        die (its job would be left running); a stopping worker leaves the job running under its pid, and the
        server gives it back to the queue (the supervisor, or the next start's recovery)."""
        while not self.stopping():
            try:
                self.store.fail(job["id"], self.pid, error)
                log.warning("job %s: failed, %s", job["id"], error)
                return
            except Exception as exc:
                if not is_disk_full(exc):
                    raise
                self._disk_full(f"cannot record that job {job['id']} failed")

    def _disk_full(self, what: str) -> None:
        """Say so and wait a little (the janitor, or an administrator, may free space meanwhile)."""
        log.warning("render worker %d: the disk is full: %s; trying again in %g s", self.pid, what, DISK_FULL_PAUSE)
        self.wait(DISK_FULL_PAUSE)
