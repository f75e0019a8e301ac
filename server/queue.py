"""The job queue: one interface, two backends.

The job store (SQLite on the API's host) is the record of every job in both; the queue only gets
each job rendered and its results back into the store.

- `EmbeddedQueue` (the default, `./dev serve`): render worker processes on this host claim queued
  jobs straight from the store and write into it (server/pool.py, server/worker.py). No other service.
- `RedisQueue` (`--redis URL` or TRACER_REDIS_URL; server/rq_queue.py): jobs go to RQ queues on Redis,
  worker hosts anywhere (`python -m server.worker --redis URL`) render them and send their progress,
  images and results back as events that the API applies to its store, fenced by the try.

The routes, the SSE streams, grading and the page see only the store and this interface.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Protocol

from server.lifecycle import Lane
from server.pool import WorkerPool
from server.settings import Settings
from server.store import HOST, JobStore

log = logging.getLogger("server.queue")


class JobQueue(Protocol):
    backend: str  # "embedded" or "redis"
    stats: dict[str, int]  # counts for GET /api/health (the Redis backend: events, stale, lost, bytes)

    def start(self) -> None:
        """At the API's start-up, after the store is open: recover, then start taking jobs."""

    def shutdown(self) -> None:
        """At the API's shutdown: running jobs of this host go back to the queue."""

    def submitted(self, row: dict) -> None:
        """The store has just queued this job: get it rendered."""

    def cancelled(self, row: dict) -> None:
        """The store has just cancelled this job (queued) or asked it to stop (running): reach it."""

    def workers(self) -> list[dict]:
        """The live workers (GET /api/health): slot, name, host, device, pid, alive, ready, job, ..."""

    def capacity(self, lane: Lane) -> int:
        """How many workers take jobs of `lane` (for a queued job's expected wait)."""


class EmbeddedQueue:
    """Worker processes on this host, claiming from the store (`workers` of them; none: jobs wait)."""

    backend = "embedded"

    def __init__(self, settings: Settings, store: JobStore, stopping: Callable[[], bool] = lambda: False):
        self.settings, self.store = settings, store
        self.stats: dict[str, int] = {}
        self.pool = WorkerPool(settings, store, stopping) if settings.workers > 0 else None

    def start(self) -> None:
        requeued, cancelled = self.store.recover()
        if requeued or cancelled:
            log.info("jobs left running by the last server: %d back in the queue, %d cancelled", requeued, cancelled)
        if self.pool is not None:
            self.pool.start()
        else:
            log.warning("no render workers (workers = 0): jobs wait in the queue")

    def shutdown(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()
            log.info("render workers stopped")

    def submitted(self, row: dict) -> None:
        if self.pool is not None:
            self.pool.notify()

    def cancelled(self, row: dict) -> None:
        pass  # a worker reads its job's row between bands

    def capacity(self, lane: Lane) -> int:
        return sum(1 for s in (self.pool.slots if self.pool else []) if lane in s.lanes)

    def workers(self) -> list[dict]:
        if self.pool is None:
            return []
        return [
            {**w, "host": HOST, "device": "cpu", "threads": self.settings.threads_per_worker()}
            for w in self.pool.info()
        ]


def make_queue(settings: Settings, store: JobStore, stopping: Callable[[], bool] = lambda: False) -> JobQueue:
    """The backend the settings ask for: Redis with RQ when `redis_url` is set, else embedded. `stopping()`
    says that the server has been asked to stop (a signal): from then on no worker is started."""
    if settings.redis_url:
        from server.rq_queue import RedisQueue

        return RedisQueue(settings, store, stopping)
    return EmbeddedQueue(settings, store, stopping)
