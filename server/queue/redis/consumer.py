"""The Redis backend's events in (a mixin of RedisQueue, server/queue/redis/queue.py): a consumer thread reads the
worker hosts' events (server/queue/redis/events.py) in a consumer group and applies each to the store, fenced by its
try: files into the job's folder, then the row. While the API's disk is full an event is not acknowledged: it is
read and applied again every few seconds until it can be written."""

from __future__ import annotations

import logging
from typing import cast

import redis

from server.core.files import is_disk_full
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, TryEnd
from server.jobs.rows import JobRow
from server.jobs.store_base import Attempt
from server.queue.redis import events as ev
from server.queue.redis.tries import RedisTries

log = logging.getLogger(__name__)

DISK_FULL_PAUSE = 2.0  # seconds between two tries to apply an event while the data directory's disk is full


# XREADGROUP's reply on a connection that answers bytes: [(stream, [(entry id, {field: value}), ...])], or
# None when nothing came within the block
StreamReply = list[tuple[bytes, list[tuple[bytes, dict[bytes, bytes]]]]] | None


class EventConsumer(RedisTries):
    """The worker hosts' events applied to the store."""

    # -- in: events into the store ------------------------------------------------------------

    def _consume(self) -> None:
        pending = True  # first the entries delivered to this consumer before and not acknowledged
        while not self.stop.is_set():
            try:
                got = cast(
                    StreamReply,
                    self.r.xreadgroup(
                        ev.GROUP, self.consumer, {ev.STREAM: "0" if pending else ">"}, count=100, block=500
                    ),
                )
                entries = got[0][1] if got else []
                if pending and not entries:
                    pending = False
                    continue
                for entry_id, fields in entries:
                    self._apply_entry(fields)
                    self.r.xack(ev.STREAM, ev.GROUP, entry_id)
            except redis.ResponseError as exc:
                if "NOGROUP" in str(exc):  # Redis lost its data: the monitor queues the jobs again
                    self._ensure_group()
                    pending = True
                else:
                    log.exception("reading the worker hosts' events")
                    self.stop.wait(1.0)
            except redis.RedisError as exc:
                log.warning("Redis unreachable while reading events (%s); retrying", exc)
                self.stop.wait(1.0)
            except Exception as exc:
                if is_disk_full(exc):  # not acknowledged: read again (every event applies twice harmlessly)
                    log.warning("the disk is full: a worker host's event waits to be applied (%s)", exc)
                    pending = True
                    self.stop.wait(DISK_FULL_PAUSE)
                    continue
                log.exception("applying a worker host's event")
                self.stop.wait(0.2)

    def _apply_entry(self, fields: dict) -> None:
        kind, job_id, attempt, data = ev.decode(fields)
        self.stats["events"] += 1
        with self.lock:
            row = self.store.get(job_id)
            if kind == ev.EventKind.started:
                if self.store.start_try(job_id, attempt, data.get("host"), data.get("device"), data.get("worker")):
                    return
                log.info("job %s: try %d started, but the job has moved on (%s)", job_id, attempt, _state(row))
                return
            current = row is not None and row["status"] == JobStatus.running and row["attempts"] == attempt
            files = data.get("files") or {}
            if not current:  # a stale try (lost, or the job was cancelled or ended): nothing of it lands
                self.stats["stale"] += 1
                if files:
                    self.r.delete(*files.values())
                log.info("job %s: %s of try %d dropped (%s)", job_id, kind, attempt, _state(row))
                return
            self._copy_files(job_id, files)
            fence = Attempt(attempt)
            if kind == ev.EventKind.progress:
                self.store.progress(job_id, fence, **data.get("fields", {}))
            elif kind == ev.EventKind.finish:
                self.store.finish(job_id, fence, JobStatus(data["status"]), **data.get("fields", {}))
                self.r.delete(ev.try_key(job_id), ev.cancel_key(job_id))
            elif kind == ev.EventKind.giveback:
                if data.get("fields"):
                    self.store.progress(job_id, fence, **data["fields"])
                outcome = TryEnd(data.get("outcome") or TryEnd.given_back)
                moved = self.store.requeue(job_id, fence, outcome)
                if moved == JobStatus.queued:
                    self._enqueue(self._row(job_id), attempt + 1)
                    log.info("job %s: try %d %s; queued as try %d", job_id, attempt, outcome, attempt + 1)
                elif moved == JobStatus.cancelled:  # its cancel was accepted while it ran: it ends here
                    self.r.delete(ev.try_key(job_id), ev.cancel_key(job_id))

    def _copy_files(self, job_id: str, files: dict[str, str]) -> None:
        if not files:
            return
        keys = list(files.values())
        blobs = self.r.mget(keys)
        for name, blob in zip(files, blobs, strict=True):
            if blob is None:
                log.warning("job %s: the file %s it sent has expired from Redis", job_id, name)
                continue
            self.stats["bytes"] += len(blob)
            self.store.save_file(job_id, JobFile(name), blob)
        self.r.delete(*keys)


def _state(row: JobRow | None) -> str:
    if row is None:
        return "the job is gone"
    return f"the job is {row['status']} on try {row['attempts']}"
