"""The job store's supervisor and worker side (a mixin of JobStore, server/jobs/store.py): an embedded worker
claims a job, reports its progress, gives it back or finishes it, always fenced (`worker = pid AND status =
running`, or a try's `Attempt`), so that a worker that lost its job can never overwrite the job's new life; the
supervisor finds a dead worker's jobs and the overdue ones."""

from __future__ import annotations

import json
import time

from server.jobs.lifecycle import LANES, BadTransition, JobStatus, Lane, TryEnd, after_lost, lost_error
from server.jobs.rows import JobRowWithScene
from server.jobs.store_base import (
    CANCELLED,
    FAILED,
    HOST,
    LANE_ORDER,
    QUEUED,
    RUNNING,
    Attempt,
    JobTables,
    Sql,
    all_of,
    begin_try,
    end_try,
    fence,
    fresh_unless_resumed,
)


class WorkerSide(JobTables):
    """The jobs' rows as the supervisor and the embedded workers change them."""

    # -- the supervisor -----------------------------------------------------------------------

    def running_on(self, pid: int) -> str | None:
        row = self._one("SELECT id FROM jobs WHERE status = ? AND worker = ?", (RUNNING, pid))
        return row["id"] if row else None

    def worker_died(self, pid: int, max_tries: int, reason: str) -> list[tuple[str, str]]:
        """The jobs of a dead embedded worker: each try is lost (`lifecycle.after_lost`: queued again while
        fewer than `max_tries` tries are lost, else failed). [(id, status)]."""
        out = []
        with self._tx() as db:
            rows = db.execute(
                "SELECT id, attempts, lost, cancel_requested FROM jobs WHERE status = ? AND worker = ?", (RUNNING, pid)
            ).fetchall()
            for r in rows:
                status = after_lost(r["lost"], max_tries, bool(r["cancel_requested"]))
                error = {CANCELLED: f"cancelled ({reason})", FAILED: lost_error(reason, r["attempts"])}.get(status)
                self._move(db, RUNNING, status, "id = ?", (r["id"],), error=error, worker=None,
                           lost=Sql("lost + 1"), tries=end_try(TryEnd.lost))  # fmt: skip
                out.append((r["id"], status.value))
        return out

    def overdue(self, grace: float) -> list[dict]:
        """Running jobs past their time limit plus `grace` seconds (their worker did not stop them)."""
        rows = self.db.execute(
            "SELECT id, worker, max_seconds FROM jobs WHERE status = ? AND started_at + max_seconds + ? < ?",
            (RUNNING, grace, time.time()),
        ).fetchall()
        return [dict(r) for r in rows]

    def fail(self, job_id: str, pid: int | None, error: str) -> bool:
        return self.finish(job_id, pid, FAILED, error=error)

    # -- the worker side ----------------------------------------------------------------------

    def claim(self, pid: int, lanes: tuple = LANES) -> JobRowWithScene | None:
        """Take the next queued job of `lanes` for worker `pid`, atomically: interactive before batch, then
        by priority, then the oldest. A job resumed from a snapshot keeps its progress and image."""
        marks = ", ".join("?" * len(lanes))
        lanes = tuple(Lane(x).value for x in lanes)
        waiting = f"status = ? AND lane IN ({marks})"
        if self.db.execute(f"SELECT 1 FROM jobs WHERE {waiting} LIMIT 1", (QUEUED, *lanes)).fetchone() is None:
            return None  # an idle worker's look at the queue takes no write lock
        with self._tx() as db:
            rows = self._move(
                db, QUEUED, RUNNING,
                f"id = (SELECT id FROM jobs WHERE {waiting} ORDER BY {LANE_ORDER}, priority DESC, created_at, rowid"
                " LIMIT 1)",
                (QUEUED, *lanes), worker=pid, started_at=time.time(), finished_at=None,
                attempts=Sql("attempts + 1"), error=None, host=HOST, device="cpu",
                **fresh_unless_resumed(), tries=begin_try("attempts + 1", HOST, "cpu", pid),
            )  # fmt: skip
        return rows[0] if rows else None

    def control(self, job_id: str, who: int) -> dict | None:
        """What a worker checks between bands: is the job still its own (None if not), and is a stop requested."""
        where, args = fence(who)
        return self._one(f"SELECT cancel_requested FROM jobs WHERE {all_of('id = ?', where, 'status = ?')}",
                         (job_id, *args, RUNNING))  # fmt: skip

    def progress(self, job_id: str, who: int, **fields) -> bool:
        """Update progress fields (samples_done, samples_total, passes_done, spp_done, rays, preview, solve) of
        its job, while `who` (a worker's pid, or a try's Attempt) still has it."""
        for key in ("rays", "solve"):
            if key in fields:
                fields[key] = json.dumps(fields[key])
        sets = ", ".join(f"{k} = ?" for k in fields)
        where, args = fence(who)
        cur = self.db.execute(
            f"UPDATE jobs SET {sets} WHERE {all_of('id = ?', where, 'status = ?')}",
            (*fields.values(), job_id, *args, RUNNING),
        )
        return cur.rowcount > 0

    def requeue(self, job_id: str, who: int, outcome: TryEnd = TryEnd.given_back) -> JobStatus | None:
        """Give a job back to the queue: its worker is shutting down (given back), or its render gives
        way to interactive work (gave way). An embedded worker's try does not count (the next claim
        counts it again); a try of the Redis backend is given back as the next try (tries are its
        fence), which counts nothing lost either. A job whose cancel was accepted ends cancelled
        instead. The status it moved to (queued or cancelled), or None if `who` no longer had it."""
        where, args = fence(who)
        again = Sql("attempts + 1") if isinstance(who, Attempt) else Sql("MAX(attempts - 1, 0)")
        with self._tx() as db:
            if self._move(
                db, RUNNING, CANCELLED, all_of("id = ?", where, "cancel_requested = 1"), (job_id, *args),
                worker=None, error=f"cancelled (its try was {outcome})", tries=end_try(CANCELLED.value),
            ):  # fmt: skip
                return CANCELLED  # a cancel accepted while it ran wins: its client was told it ends cancelled
            moved = self._move(
                db, RUNNING, QUEUED, all_of("id = ?", where), (job_id, *args),
                worker=None, attempts=again, tries=end_try(outcome),
            )  # fmt: skip
        return QUEUED if moved else None

    def interactive_waiting(self, longer_than: float = 1.0) -> bool:
        """Is interactive work waiting (queued for more than `longer_than` seconds: a free interactive
        worker would have taken it)? Then a batch render gives way at its next pass."""
        row = self.db.execute(
            "SELECT 1 FROM jobs WHERE status = ? AND lane = ? AND created_at < ? LIMIT 1",
            (QUEUED, Lane.interactive.value, time.time() - longer_than),
        ).fetchone()
        return row is not None

    def finish(self, job_id: str, who: int | None, status: JobStatus, **fields) -> bool:
        """End a running job as `status` (done, failed or cancelled), with its last progress `fields`;
        only while `who` (a worker's pid, a try's Attempt) still has it (anyone's when None: the
        supervisor). False if it had not. A job whose cancel was accepted while it ran ends cancelled
        whatever `status` says (a render that finished its last band before it saw the cancel): the
        job's end agrees with the 202 its client got."""
        if not JobStatus(status).finished:
            raise BadTransition(f"finish() ends a job; {status} is not an end")
        for key in ("rays", "errors", "solve"):
            if key in fields:
                fields[key] = json.dumps(fields[key])
        status = JobStatus(status)
        where, args = fence(who)
        mine = (all_of("id = ?", where), (job_id, *args))
        with self._tx() as db:
            if status is not CANCELLED:  # a cancel accepted while it ran (202) wins, whatever the try's end
                error = f"cancelled ({fields['error']})" if fields.get("error") else "cancelled while rendering"
                cancelled = {**fields, "error": error, "tries": end_try(CANCELLED.value)}
                if self._move(db, RUNNING, CANCELLED, all_of(mine[0], "cancel_requested = 1"), mine[1], **cancelled):
                    return True
            fields.setdefault("tries", end_try(status.value))
            return bool(self._move(db, RUNNING, status, *mine, **fields))
