"""The embedded backend's side of the queue interface (server/queue/base.py): the worker pool of this host."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from server.core.settings import Settings
from server.jobs.lifecycle import Lane
from server.jobs.rows import JobRowWithScene
from server.jobs.store import JobStore
from server.jobs.store_base import HOST
from server.queue.embedded.pool import WorkerPool

log = logging.getLogger(__name__)


class EmbeddedQueue:
    """Worker processes on this host, claiming from the store (`workers` of them; none: jobs wait)."""

    backend = "embedded"

    def __init__(self, settings: Settings, store: JobStore, stopping: Callable[[], bool] = lambda: False):
        self.settings, self.store = settings, store
        self.stats: dict[str, int] = {}
        self.pool = WorkerPool(settings, store, stopping) if settings.workers > 0 else None

    def start(self, kernels: threading.Event | None = None) -> None:
        requeued, cancelled = self.store.recover()
        if requeued or cancelled:
            log.info("jobs left running by the last server: %d back in the queue, %d cancelled", requeued, cancelled)
        if self.pool is not None:
            self.pool.start(kernels)
        else:
            log.warning("no render workers (workers = 0): jobs wait in the queue")

    def shutdown(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()
            log.info("render workers stopped")

    def submitted(self, row: JobRowWithScene) -> None:
        if self.pool is not None:
            self.pool.notify()

    def cancelled(self, row: JobRowWithScene) -> None:
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
