"""Where a try reports (server/queue/render_try.py): the `Channel` protocol, and the embedded backend's
`StoreChannel` (a worker process on the API's host writing into the job store). A worker host of the Redis
backend reports through its own channel (server/queue/redis/host.py)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, Stop, TryEnd
from server.jobs.store import JobStore


class Channel(Protocol):
    """Where a try reports (the job store here, or a worker host's Redis events)."""

    def stop_reason(self) -> Stop | None:
        """Stop.cancel (the job was cancelled), Stop.lost (it is no longer this try's), Stop.shutdown (the
        host asks for the job back), or None: go on."""
        ...

    def should_yield(self) -> bool:
        """Is interactive work waiting for this worker? (asked of a batch render at each pass)"""
        ...

    def snapshot(self) -> bytes | None:
        """The film this try continues from (a snapshot of an earlier try of the job), or None."""
        ...

    def progress(self, **fields) -> None:
        """Progress fields: samples_done, samples_total, passes_done, spp_done, rays, preview, solve,
        snapshot (the pass of the film just saved)."""

    def save(self, kind: JobFile, data: bytes | str) -> None:
        """One of the job's files, whole (it reaches the job's folder on the API host before the next
        progress or finish that follows it)."""

    def finish(self, status: JobStatus, **fields) -> None:
        """The try ended the job: done, failed or cancelled, with its last progress fields."""

    def give_back(self, outcome: TryEnd = TryEnd.given_back, **fields) -> None:
        """The job goes back to the queue: the host is shutting down (given back), or the render gives
        way to interactive work (gave way, its film saved just before)."""


class StoreChannel:
    """The embedded backend: a worker process on the API's host writes into the job store, fenced by
    its pid (a worker that lost its job can never write into the job's next life)."""

    def __init__(self, store: JobStore, job: Mapping[str, Any], pid: int):
        self.store, self.job, self.job_id, self.pid = store, job, job["id"], pid

    def stop_reason(self) -> Stop | None:
        row = self.store.control(self.job_id, self.pid)
        if row is None:
            return Stop.lost  # the job is no longer ours (the server gave it to another worker)
        return Stop.cancel if row["cancel_requested"] else None

    def should_yield(self) -> bool:
        return self.store.interactive_waiting()

    def snapshot(self) -> bytes | None:
        if not self.job.get("snapshot"):
            return None
        try:
            return self.store.job_file(self.job_id, JobFile.snapshot).read_bytes()
        except OSError:
            return None

    def progress(self, **fields) -> None:
        self.store.progress(self.job_id, self.pid, **fields)

    def save(self, kind: JobFile, data: bytes | str) -> None:
        self.store.save_file(self.job_id, kind, data)

    def finish(self, status: JobStatus, **fields) -> None:
        self.store.finish(self.job_id, self.pid, status, **fields)

    def give_back(self, outcome: TryEnd = TryEnd.given_back, **fields) -> None:
        if fields:
            self.store.progress(self.job_id, self.pid, **fields)
        self.store.requeue(self.job_id, self.pid, outcome)
