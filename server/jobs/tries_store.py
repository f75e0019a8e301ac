"""The Redis backend's tries of jobs on worker hosts, applied by the API to the job store (a mixin of JobStore,
server/jobs/store.py): a try queued in Redis, taken by a host, lost with it; the live jobs it watches."""

from __future__ import annotations

import time

from server.jobs.lifecycle import JobStatus, TryEnd, after_lost, lost_error
from server.jobs.rows import JobRowWithScene
from server.jobs.store_base import CANCELLED, QUEUED, RUNNING, JobTables, Sql, begin_try, end_try, fresh_unless_resumed


class TryTables(JobTables):
    """The jobs' rows as the Redis backend's tries change them."""

    # -- the Redis backend: tries of jobs on worker hosts, applied by the API --------------------

    def queue_try(self, job_id: str, attempt: int) -> bool:
        """A queued job's try `attempt` has been put in Redis (its first, or again after Redis lost it)."""
        return (
            self.db.execute(
                "UPDATE jobs SET attempts = ? WHERE id = ? AND status = ?", (attempt, job_id, QUEUED)
            ).rowcount
            > 0
        )

    def start_try(
        self, job_id: str, attempt: int, host: str | None, device: str | None, worker: str | None
    ) -> JobRowWithScene | None:
        """A worker host took try `attempt` of a queued job: it runs (None if the job moved on: cancelled,
        or a later try). The host, device and worker are as its event named them (None where it did not)."""
        rows = self._move(
            self.db, QUEUED, RUNNING, "id = ? AND attempts = ?", (job_id, attempt),
            worker=None, started_at=time.time(), finished_at=None, **fresh_unless_resumed(), error=None,
            host=host, device=device,
            tries=begin_try("attempts", host, device, worker),
        )  # fmt: skip
        return rows[0] if rows else None

    def lose_try(self, job_id: str, attempt: int, reason: str, max_tries: int) -> tuple[str, int] | None:
        """Try `attempt` of a queued or running job was lost with its worker host (`lifecycle.after_lost`: the
        job goes back to the queue as the next try while fewer than `max_tries` tries are lost, else it fails
        with `reason`). Returns (new status, attempt to queue) or None if the job had moved on."""
        with self._tx() as db:
            row = db.execute(
                "SELECT status, lost, cancel_requested FROM jobs WHERE id = ? AND attempts = ?", (job_id, attempt)
            ).fetchone()
            if row is None or row["status"] not in (QUEUED, RUNNING):
                return None
            source = JobStatus(row["status"])
            end = end_try(TryEnd.lost) if source is RUNNING else Sql("tries")
            status = after_lost(row["lost"], max_tries, bool(row["cancel_requested"]))
            if status is not QUEUED:
                error = f"cancelled ({reason})" if status is CANCELLED else lost_error(reason, attempt)
                self._move(db, source, status, "id = ?", (job_id,), error=error, lost=Sql("lost + 1"), tries=end)
                return status.value, attempt
            if source is RUNNING:
                self._move(db, RUNNING, QUEUED, "id = ?", (job_id,), attempts=Sql("attempts + 1"),
                           lost=Sql("lost + 1"), tries=end)  # fmt: skip
            else:
                db.execute("UPDATE jobs SET attempts = attempts + 1, lost = lost + 1 WHERE id = ?", (job_id,))
            return QUEUED.value, attempt + 1

    def live_tries(self) -> list[dict]:
        """The queued and running jobs: what the Redis backend watches (id, status, attempts, started_at,
        max_seconds, cancel_requested)."""
        rows = self.db.execute(
            "SELECT id, status, attempts, started_at, max_seconds, cancel_requested, priority FROM jobs"
            " WHERE status IN (?, ?) ORDER BY priority DESC, created_at, rowid",
            (QUEUED, RUNNING),
        ).fetchall()
        return [dict(r) for r in rows]
