"""The embedded backend's render worker: a process on the API's host that takes jobs from the SQLite
queue and renders them (server/rendering.py), reporting straight into the job store.

Started by the server (server/pool.py) with the "spawn" method, it loads the Warp kernels once,
then loops: claim the next job (priority, then age; an idle worker sleeps until the server signals
a submission, or `poll_interval` at most) and render it. Only plain data crosses the process
boundary: the job row in SQLite, the settings as a dict, and the image files.

`python -m server.worker --redis URL` is the other backend's worker host (server/rq_worker.py).
"""

from __future__ import annotations

import logging
import os
import signal

from server.channel import WorkerEnd
from server.lifecycle import LANES
from server.rendering import StoreChannel, Try
from server.settings import Settings
from server.store import JobStore

log = logging.getLogger("server.worker")


def worker_main(settings_data: dict, conn, lanes: list[str] | None = None) -> None:
    """Entry point of a worker process (spawned: it imports everything itself); `conn` is its end of
    the server's line (server/channel.py): wakes come in, "ready" goes out, end-of-file means stop."""
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
    line.ready()
    Worker(settings, JobStore(settings.data_dir), line.stopping, lanes=tuple(lanes or LANES)).loop(line.wait)


def load_kernels() -> None:
    """Compile (or load from Warp's disk cache) the render kernels, once per process."""
    from tracer.render import load_kernels as load

    load("cpu")


class Worker:
    """Claims and renders jobs; `stopping()` says the process should give its job back and exit."""

    def __init__(self, settings: Settings, store: JobStore, stopping, pid: int | None = None, lanes: tuple = LANES):
        self.settings, self.store, self.stopping = settings, store, stopping
        self.pid = pid or os.getpid()
        self.lanes = lanes
        from tracer.radiosity import SolutionCache

        self.cache = SolutionCache(settings.cache_dir or settings.data_dir / "cache" / "radiosity")

    def loop(self, wait) -> None:
        log.info("render worker %d ready", self.pid)
        while not self.stopping():
            job = self.store.claim(self.pid, self.lanes)
            if job is None:
                wait(self.settings.poll_interval)
                continue
            self.run(job)
        log.info("render worker %d stopping", self.pid)

    def run(self, job: dict) -> str:
        """One try of a claimed job, reported into the store; how it ended (see rendering.Try.run)."""
        log.info("job %s: rendering (try %d)", job["id"], job["attempts"])
        channel = StoreChannel(self.store, job, self.pid)
        settings = self.settings
        return Try(
            job, channel, settings.limits, settings.threads_per_worker(), settings.preview_interval, self.stopping,
            cache=self.cache, snapshot_interval=settings.snapshot_interval,
        ).run()  # fmt: skip


if __name__ == "__main__":  # python -m server.worker --redis URL ...: a worker host of the Redis backend
    import sys

    from server.rq_worker import main

    sys.exit(main())
