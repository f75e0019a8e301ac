"""A try of the Redis backend in a worker host's work horse (server/queue/redis/host.py starts the host): `run_try`,
the RQ job, renders one try (server/queue/render_try.py) and reports through `RedisChannel`: events on the
stream, files as keys (server/queue/redis/events.py). The API applies them to its store.

`HOST` is what the host set up before any fork (its Redis URL, device, threads, name, process id, cache) and
`STOP` whether it is stopping: a try gives its job back at its next check (within a band of rows). A horse
stopped by a SIGTERM of its own (a service manager that signals every process of its unit) gives its try back
too, and so does a horse whose host is gone (a SIGKILL to the host's group).
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import threading
import time
from datetime import UTC, datetime
from typing import cast

import redis
from redis.typing import EncodableT, FieldT
from rq import Queue

from server.core.exits import Stopping
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, Stop, TryEnd
from server.queue.redis import events as ev
from server.queue.render_try import Try
from tracer.radiosity import SolutionCache

log = logging.getLogger(__name__)

HOST = {"url": None, "device": "cpu", "threads": 1, "name": None, "host": socket.gethostname(), "cache": None}
SEND_RETRY_SECONDS = 60.0  # how long a try keeps sending its final event while Redis is unreachable
HOST_CHECK = 0.5  # s between a work horse's looks at whether its host is still there


STOP = Stopping()  # whether this host is stopping (in a work horse: whether its try gives its job back)


def connect(url: str) -> redis.Redis:
    return redis.Redis.from_url(url, socket_timeout=10, socket_connect_timeout=5, health_check_interval=5)


class RedisChannel:
    """A try's reports to the API through Redis (server/queue/channel.py's Channel)."""

    def __init__(self, r: redis.Redis, job_id: str, attempt: int, snapshot_key: str | None = None):
        self.r, self.job_id, self.attempt, self.snapshot_key = r, job_id, attempt, snapshot_key
        self.files: dict[str, str] = {}  # JobFile value -> key, sent with the next event
        self.serial = 0
        self.bytes_sent = 0
        self.unreachable = 0  # reports that could not reach Redis (dropped, or retried for the final one)

    def _send(self, kind: ev.EventKind, **data) -> None:
        entry = ev.encode(kind, self.job_id, self.attempt, **data)
        fields: dict[FieldT, EncodableT] = {**entry}
        self.r.xadd(ev.STREAM, fields, maxlen=ev.STREAM_MAXLEN, approximate=True)
        self.bytes_sent += sum(len(v) for v in entry.values())

    def started(self, worker: str) -> None:
        self._send(ev.EventKind.started, host=HOST["host"], device=HOST["device"], worker=worker)

    def stop_reason(self) -> Stop | None:
        if STOP():
            return Stop.shutdown
        try:
            cancel, current, giveback = self.r.mget(
                ev.cancel_key(self.job_id), ev.try_key(self.job_id), ev.giveback_key(self.job_id, self.attempt)
            )
        except redis.RedisError:
            self.unreachable += 1
            return None  # cut off: render on; what it sends later is fenced if the job moved on meanwhile
        if cancel:
            return Stop.cancel
        if current is not None and int(current) != self.attempt:
            return Stop.lost
        if giveback:
            return Stop.shutdown
        return None

    def should_yield(self) -> bool:
        """Interactive work waits in its queue for more than a second (a free host would have taken it)."""
        try:
            first = self.r.lindex(Queue(ev.QUEUES[0], connection=self.r).key, 0)
            if first is None:
                return False
            enqueued = self.r.hget(f"rq:job:{ev.text(first)}", "enqueued_at")
        except redis.RedisError:
            return False
        if enqueued is None:
            return False
        when = datetime.fromisoformat(ev.text(enqueued).replace("Z", "+00:00"))
        if when.tzinfo is None:
            when = when.replace(tzinfo=UTC)
        return (datetime.now(UTC) - when).total_seconds() > 1.0

    def snapshot(self) -> bytes | None:
        if not self.snapshot_key:
            return None
        try:
            return cast(bytes | None, self.r.get(self.snapshot_key))  # (bytes: decode_responses is off)
        except redis.RedisError:
            return None

    def save(self, kind: JobFile, data: bytes | str) -> None:
        raw = data.encode() if isinstance(data, str) else data
        self.serial += 1
        key = ev.blob_key(self.job_id, self.attempt, self.serial)
        try:
            self.r.set(key, raw, ex=ev.BLOB_TTL)
        except redis.RedisError:
            self.unreachable += 1
            return
        self.bytes_sent += len(raw)
        self.files[JobFile(kind).value] = key

    def progress(self, **fields) -> None:
        try:
            self._send(ev.EventKind.progress, fields=fields, files=self.files)
            self.files = {}
        except redis.RedisError:
            self.unreachable += 1  # a later report carries the state again

    def finish(self, status: JobStatus, **fields) -> None:
        self._final(ev.EventKind.finish, status=JobStatus(status).value, fields=fields, files=self.files)

    def give_back(self, outcome: TryEnd = TryEnd.given_back, **fields) -> None:
        self._final(ev.EventKind.giveback, outcome=outcome, fields=fields, files=self.files)

    def _final(self, kind: ev.EventKind, **data) -> None:
        """The last word of a try: retried while Redis is unreachable (a cut cable may come back)."""
        deadline = time.monotonic() + SEND_RETRY_SECONDS
        while True:
            try:
                self._send(kind, **data)
                return
            except redis.RedisError:
                self.unreachable += 1
                if time.monotonic() > deadline:
                    log.warning("job %s try %d: Redis unreachable; its %s is lost", self.job_id, self.attempt, kind)
                    return
                time.sleep(1.0)


def run_try(payload: dict) -> dict:
    """The RQ job: one try of one job, in the work horse (forked from the worker, kernels loaded).
    `payload`: {job: {id, scene, max_seconds, samples_total, attempts}, limits: {...}, preview_interval}."""
    from rq import get_current_job

    from tracer.scene import Limits

    job = payload["job"]
    if os.getpid() != HOST["pid"]:
        _horse_watch(HOST["pid"])
    r = connect(HOST["url"])
    channel = RedisChannel(r, job["id"], int(job["attempts"]), payload.get("snapshot_key"))
    rq_job = get_current_job()
    channel.started(HOST["name"] or (rq_job.worker_name if rq_job else None) or HOST["host"])
    limits = Limits(**payload["limits"])
    ended = Try(
        job, channel, limits, HOST["threads"], payload["preview_interval"], STOP, device=HOST["device"],
        cache=SolutionCache(HOST["cache"]), snapshot_interval=payload.get("snapshot_interval", 10.0),
    ).run()  # fmt: skip
    return {"ended": ended, "bytes_sent": channel.bytes_sent, "unreachable": channel.unreachable}


def _horse_watch(host: int) -> None:
    """In a forked work horse: its try gives its job back (STOP) on a SIGTERM of its own, or once its host is
    gone (killed with its process group, which the horse is not in)."""
    signal.signal(signal.SIGTERM, lambda signum, frame: STOP.set())

    def watch() -> None:
        while not STOP.wait(HOST_CHECK):
            if os.getppid() != host:
                log.warning("work horse %d: its worker host %d is gone; giving the try back", os.getpid(), host)
                STOP.set()

    threading.Thread(target=watch, name="host-watch", daemon=True).start()
