"""The job queue: one interface, two backends.

The job store (SQLite on the API's host) is the record of every job in both; the queue only gets
each job rendered and its results back into the store.

- `EmbeddedQueue` (the default, `./dev serve`): render worker processes on this host claim queued
  jobs straight from the store and write into it (server/queue/embedded/). No other service.
- `RedisQueue` (`--redis URL` or TRACER_REDIS_URL; server/queue/redis/queue.py): jobs go to RQ queues on Redis,
  worker hosts anywhere (`python -m server.worker --redis URL`) render them and send their progress,
  images and results back as events that the API applies to its store, fenced by the try.

The routes, the SSE streams, grading and the page see only the store and this interface.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Protocol

from server.core.settings import Settings
from server.jobs.lifecycle import Lane
from server.jobs.rows import JobRowWithScene
from server.jobs.store import JobStore

log = logging.getLogger(__name__)


class JobQueue(Protocol):
    backend: str  # "embedded" or "redis"
    stats: dict[str, int]  # counts for GET /api/health (the Redis backend: events, stale, lost, bytes)

    def start(self, kernels: threading.Event | None = None) -> None:
        """At the API's start-up, after the store is open: recover, then start taking jobs; this host's workers
        start once `kernels` is set (the render kernels are in Warp's cache), at once without it."""

    def shutdown(self) -> None:
        """At the API's shutdown: running jobs of this host go back to the queue."""

    def submitted(self, row: JobRowWithScene) -> None:
        """The store has just queued this job: get it rendered."""

    def cancelled(self, row: JobRowWithScene) -> None:
        """The store has just cancelled this job (queued) or asked it to stop (running): reach it."""

    def workers(self) -> list[dict]:
        """The live workers (GET /api/health): slot, name, host, device, pid, alive, ready, job, ..."""
        ...

    def capacity(self, lane: Lane) -> int:
        """How many workers take jobs of `lane` (for a queued job's expected wait)."""
        ...


def make_queue(settings: Settings, store: JobStore, stopping: Callable[[], bool] = lambda: False) -> JobQueue:
    """The backend the settings ask for: Redis with RQ when `redis_url` is set, else embedded. `stopping()`
    says that the server has been asked to stop (a signal): from then on no worker is started."""
    if settings.redis_url:
        from server.queue.redis.queue import RedisQueue

        return RedisQueue(settings, store, stopping)
    from server.queue.embedded.queue import EmbeddedQueue

    return EmbeddedQueue(settings, store, stopping)
