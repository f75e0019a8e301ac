"""The Redis backend's state on the API (RedisQueue, server/queue/redis/queue.py, is this class with its event
consumer and its monitor) and its tries out into RQ: a queued job's try enqueued (the store records which try is
out), and every try Redis does not know sent again."""

from __future__ import annotations

import logging
import subprocess
import threading
import time
from collections.abc import Callable

import redis
from rq import Queue
from rq.job import Job

from server.core.settings import Settings
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus
from server.jobs.rows import JobRowWithScene
from server.jobs.store import JobStore
from server.jobs.store_base import Attempt
from server.queue.redis import events as ev

log = logging.getLogger(__name__)

HARD_GRACE = 10.0  # seconds past a try's time limit before the API fails it (its host stops it itself at the limit)


class RedisTries:
    """The queue's connection, lock and counters, and the tries it sends (the base of the consumer and the
    monitor, server/queue/redis/consumer.py and monitor.py)."""

    mark: str  # this API's mark in Redis (RedisQueue.start)

    def __init__(
        self,
        settings: Settings,
        store: JobStore,
        stopping: Callable[[], bool] = lambda: False,
        clock: Callable[[], float] = time.time,
    ):
        self.settings, self.store = settings, store
        self.clock = clock  # the wall clock of the monitor's graces and time limits (a test's own)
        self.stopping = stopping  # the server has been asked to stop: its local worker hosts are not restarted
        assert settings.redis_url is not None  # (make_queue picks this backend for a Redis URL)
        self.url: str = settings.redis_url
        self.r = redis.Redis.from_url(self.url, socket_timeout=10, socket_connect_timeout=5, health_check_interval=5)
        self.queues = {name: Queue(name, connection=self.r) for name in ev.QUEUES}
        self.lock = threading.RLock()
        self.stop = threading.Event()
        self.threads: list[threading.Thread] = []
        self.consumer = "api"  # one API per Redis: the same name after a restart finds what it had not acknowledged
        self.epoch: bytes | None = None
        self._workers: tuple[float, list[dict]] | None = None  # (when, the worker hosts) as last read from Redis
        self.died_since: dict[str, float] = {}  # rq id -> when its render process was first seen dead
        self.hosts: list[subprocess.Popen | None] = [None] * settings.workers
        self.stats = {"events": 0, "stale": 0, "bytes": 0, "lost": 0}
        self.unsent = False  # a job was queued in the store while Redis was unreachable: the monitor sends it

    # -- out: tries into RQ -------------------------------------------------------------------

    def _row(self, job_id: str) -> JobRowWithScene:
        """The row of a job that is there: queued or running (a job's row goes only after it finished)."""
        row = self.store.get(job_id)
        assert row is not None
        return row

    def _enqueue(self, row: JobRowWithScene, attempt: int) -> None:
        """Put try `attempt` of a queued job into RQ (the store records it first)."""
        job_id = row["id"]
        self.store.queue_try(job_id, attempt)
        self.r.set(ev.try_key(job_id), attempt, ex=ev.FLAG_TTL)
        job = {k: row[k] for k in ("id", "kind", "lane", "params", "scene", "max_seconds", "samples_total")}
        job.update(attempts=attempt, snapshot=row["snapshot"], preview=row["preview"])
        payload = {
            "job": job,
            "limits": {k: getattr(self.settings.limits, k) for k in self.settings.limits.__dataclass_fields__},
            "preview_interval": self.settings.preview_interval,
            "snapshot_interval": self.settings.snapshot_interval,
        }
        if row["snapshot"]:  # the film to continue from travels with the try
            try:
                data = self.store.job_file(job_id, JobFile.snapshot).read_bytes()
            except OSError:
                job["snapshot"] = 0
            else:
                key = ev.snapshot_key(job_id, attempt)
                self.r.set(key, data, ex=ev.BLOB_TTL)
                payload["snapshot_key"] = key
        self.queues[row["lane"]].enqueue_call(
            "server.queue.redis.horse.run_try",
            kwargs={"payload": payload},
            job_id=ev.rq_job_id(job_id, attempt),
            timeout=int(row["max_seconds"] + 2 * HARD_GRACE),
            result_ttl=600,
            failure_ttl=24 * 3600,
            at_front=row["priority"] > 0,
            description=f"render job {job_id} try {attempt}",
        )

    def _requeue_missing(self) -> None:
        """Every queued job whose try is not in Redis (the API stopped before it went out, or Redis lost
        it) goes out again; running ones whose try Redis no longer knows run again as the next try."""
        with self.lock:
            for row in self.store.live_tries():
                attempt = max(1, row["attempts"])
                if self.r.exists(Job.key_for(ev.rq_job_id(row["id"], attempt))):
                    continue
                full = self._row(row["id"])
                if row["status"] == JobStatus.queued:
                    self._enqueue(full, attempt)
                elif self.store.requeue(row["id"], Attempt(attempt)) == JobStatus.queued:  # not counted as lost
                    self._enqueue(self._row(row["id"]), attempt + 1)
                    log.warning("job %s: its try %d is gone from Redis; queued again", row["id"], attempt)

    def _ensure_group(self) -> None:
        try:
            self.r.xgroup_create(ev.STREAM, ev.GROUP, id="0", mkstream=True)
        except redis.ResponseError as exc:
            if "BUSYGROUP" not in str(exc):
                raise
