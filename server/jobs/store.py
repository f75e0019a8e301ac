"""The job store: one SQLite table under the data directory, and each job's files beside it.

Every process and thread opens its own connection (WAL mode, so readers never wait for the
worker's writes; a busy timeout for the rare writer-writer overlap), and every statement is short.

Statuses change only through `_move`, one UPDATE per move of the life cycle (server/jobs/lifecycle.py):
its WHERE names the status the job leaves, so a move that lost a race changes nothing (a cancel of
a job that has just started, a finish of a job the supervisor has just failed). A worker writes to a
job only while the row still names it (`worker = pid AND status = running`), so a worker that lost
its job (killed and retried elsewhere, or a stale one after a restart) can never overwrite the
job's new life.

A job's files (its images, AOV pictures, radiosity solution) live in DATA/jobs/<id>/, named by
`JobFile`; routes and workers both ask the store for them (`job_file`, `save_file`).
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import cast

from server.core.db import thread_connection
from server.core.files import write_atomic
from server.core.ids import looks_like_job_id, new_job_id
from server.jobs.files import JobFile
from server.jobs.lifecycle import FINISHED, LANE_RANK, LANES, JobKind, JobStatus, Lane
from server.jobs.rows import JobRow, JobRowWithScene, job_row, job_row_sceneless
from server.jobs.store_base import CANCELLED, FINISHED_IN, LANE_ORDER, QUEUED, RUNNING
from server.jobs.tries_store import TryTables
from server.jobs.worker_store import WorkerSide


class QueueFull(Exception):
    """The queue is full (`args`: the jobs waiting, and "owner" when it is the owner's share that is; or the owner's
    renders waiting or running, and "active", when the owner has their fair share of the workers)."""


class JobStore(WorkerSide, TryTables):
    """The jobs' rows and files (the base: server/jobs/store_base.py; the workers' side and the Redis tries:
    the mixins)."""

    # -- files --------------------------------------------------------------------------------

    def job_dir(self, job_id: str) -> Path:
        """The job's folder of files (it may not exist yet: the first save makes it)."""
        return self.jobs_dir / job_id

    def job_file(self, job_id: str, kind: JobFile) -> Path:
        """Where the job's file of that kind is kept (it may not exist)."""
        return self.job_dir(job_id) / JobFile(kind).value

    def save_file(self, job_id: str, kind: JobFile, data: bytes | str | Callable[[Path], None]) -> None:
        """Write one of the job's files whole: bytes, text, or `data(path)` writing a temporary file."""
        if isinstance(data, bytes):
            write_atomic(self.job_file(job_id, kind), lambda tmp: tmp.write_bytes(data))
        elif isinstance(data, str):
            write_atomic(self.job_file(job_id, kind), lambda tmp: tmp.write_text(data))
        else:
            write_atomic(self.job_file(job_id, kind), data)

    # -- the API side -------------------------------------------------------------------------

    def create(
        self,
        scene_json: str,
        *,
        name: str | None,
        width: int,
        height: int,
        spp: int,
        priority: int,
        warnings: list,
        max_seconds: float,
        max_queued: int,
        kind: JobKind = JobKind.render,
        lane: Lane = Lane.interactive,
        params: dict | None = None,
        estimate: float | None = None,
        samples_total: int | None = None,
        owner: str | None = None,
        max_queued_owner: int | None = None,
        max_active_owner: int | None = None,
        result_key: str | None = None,
    ) -> JobRowWithScene:
        """Queue a job (`owner`: its token's hash; None: the instructor's); raises QueueFull when `max_queued`
        jobs already wait, or `max_queued_owner` of the same owner, or (a render) `max_active_owner` renders of
        the same owner wait or run."""
        job_id = new_job_id()
        total = samples_total if samples_total is not None else width * height * spp
        with self._tx() as db:
            queued = db.execute("SELECT COUNT(*) FROM jobs WHERE status = ?", (QUEUED,)).fetchone()[0]
            if queued >= max_queued:
                raise QueueFull(queued)
            if owner is not None and max_queued_owner is not None:
                mine = db.execute("SELECT COUNT(*) FROM jobs WHERE owner = ? AND status = ?", (owner, QUEUED))
                waiting = mine.fetchone()[0]
                if waiting >= max_queued_owner:
                    raise QueueFull(waiting, "owner")
            if owner is not None and max_active_owner is not None and JobKind(kind) is JobKind.render:
                active = db.execute(
                    "SELECT COUNT(*) FROM jobs WHERE owner = ? AND kind = ? AND status IN (?, ?)",
                    (owner, JobKind.render.value, QUEUED, RUNNING),
                ).fetchone()[0]
                if active >= max_active_owner:
                    raise QueueFull(active, "active")
            db.execute(
                "INSERT INTO jobs (id, status, priority, created_at, name, scene, warnings, width, height, spp,"
                " samples_total, max_seconds, kind, lane, params, estimate, owner, result_key)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (job_id, QUEUED, priority, time.time(), name, scene_json, json.dumps(warnings), width, height, spp,
                 total, max_seconds, JobKind(kind).value, Lane(lane).value, json.dumps(params or {}), estimate,
                 owner, result_key),
            )  # fmt: skip
        made = self.get(job_id)
        assert made is not None  # inserted just above
        return made

    def done_result(self, key: str, device: str) -> JobRowWithScene | None:
        """The latest render done on `device` whose result has this key (server/jobs/results.py), or None."""
        return self._job(
            "SELECT * FROM jobs WHERE result_key = ? AND status = ? AND device = ? AND cancel_requested = 0"
            " ORDER BY finished_at DESC LIMIT 1",
            (key, JobStatus.done.value, device),
        )

    def has_result(self, key: str) -> bool:
        """Whether a render of result `key` is queued, running or done (on whatever device)."""
        live = (QUEUED, RUNNING, JobStatus.done.value)
        row = self.db.execute("SELECT 1 FROM jobs WHERE result_key = ? AND status IN (?, ?, ?) LIMIT 1", (key, *live))
        return row.fetchone() is not None

    def create_answered(
        self,
        source: JobRow,
        link: Callable[[str], bool],
        *,
        scene_json: str,
        name: str | None,
        priority: int,
        warnings: list,
        lane: Lane,
        estimate: float | None,
        owner: str | None,
    ) -> JobRowWithScene | None:
        """A job of `scene_json` done at once with the result of the done job `source` (same key): its row, as
        long as the render took (an elapsed time that says what the render cost), once `link(new_id)` has put
        the files in its folder; None when it could not (the source's files have gone)."""
        job_id = new_job_id()
        if not link(job_id):
            return None
        now = time.time()
        took = max(0.0, (source["finished_at"] or now) - (source["started_at"] or now))
        copied = "width height spp max_seconds samples_done samples_total passes_done spp_done rays preview"
        copied += " errors solve host device kind params result_key"  # what the render made, as it made it
        whole: dict[str, object] = dict(source)
        fields = {c: whole[c] for c in copied.split()}
        fields.update(id=job_id, scene=scene_json, status=JobStatus.done.value, priority=priority, created_at=now,
                      started_at=now - took, finished_at=now, name=name, warnings=json.dumps(warnings),
                      lane=Lane(lane).value, estimate=estimate, owner=owner, answered_from=source["id"])  # fmt: skip
        with self._tx() as db:
            db.execute(f"INSERT INTO jobs ({', '.join(fields)}) VALUES ({', '.join('?' * len(fields))})",
                       tuple(fields.values()))  # fmt: skip
        return self.get(job_id)

    def get(self, job_id: str) -> JobRowWithScene | None:
        return self._job("SELECT * FROM jobs WHERE id = ?", (job_id,))

    def peek(self, job_id: str, wait: bool = False) -> JobRow | None:
        """The job's row without its scene. Without `wait`, read without waiting: for the event loop's own
        thread, where a trip through the thread pool costs more than the read (one row by its key; in WAL mode
        no writer blocks a reader); raises sqlite3.OperationalError where it would have to wait for a lock
        (the caller then reads with `wait`, in a thread)."""
        conn = self.db if wait else thread_connection(self._quick, self.db_path, busy_ms=0, opened=self._opened)
        row = conn.execute(f"SELECT {self._sceneless()} FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return job_row_sceneless(row) if row is not None else None

    def rows(self, ids: Iterable[str]) -> dict[str, JobRow]:
        """The rows of these jobs (those that exist) without their scenes, in one query per 500 ids: what the
        job service's watcher compares from one look to the next (server/jobs/service.py)."""
        return {k: cast(JobRow, r) for k, r in self._many(ids, self._sceneless()).items()}

    def states(self, ids: Iterable[str]) -> dict[str, dict]:
        """What a grading run needs of its render jobs (status, error, spp_done, started_at, finished_at)."""
        return self._many(ids, "id, status, error, spp_done, started_at, finished_at")

    def _many(self, ids: Iterable[str], columns: str) -> dict[str, dict]:
        ids = list(ids)
        out = {}
        for i in range(0, len(ids), 500):
            part = ids[i : i + 500]
            rows = self.db.execute(f"SELECT {columns} FROM jobs WHERE id IN ({', '.join('?' * len(part))})", part)
            out.update({r["id"]: dict(r) for r in rows})
        return out

    def _sceneless(self) -> str:
        """SQL: every column of a job's row but its scene."""
        return ", ".join(c for c in self._columns() if c != "scene")

    def _columns(self) -> list[str]:
        if not hasattr(self, "_column_names"):
            self._column_names = [r["name"] for r in self.db.execute("PRAGMA table_info(jobs)")]
        return self._column_names

    def list_jobs(
        self,
        status: str | None = None,
        limit: int = 100,
        offset: int = 0,
        kind: str | None = JobKind.render,
        owner: str | None = None,
    ) -> tuple[list[JobRowWithScene], int]:
        """Jobs newest first: of one status if given, of one kind (renders unless said; None: every kind), of
        one owner if given (a token's hash)."""
        conds = [(c, a) for c, a in (("status = ?", status), ("kind = ?", kind), ("owner = ?", owner)) if a is not None]
        where = ("WHERE " + " AND ".join(c for c, _ in conds)) if conds else ""
        args = tuple(str(a) for _, a in conds)
        rows = self.db.execute(
            f"SELECT * FROM jobs {where} ORDER BY created_at DESC, rowid DESC LIMIT ? OFFSET ?",
            (*args, limit, offset),
        ).fetchall()
        count = self.db.execute(f"SELECT COUNT(*) FROM jobs {where}", args).fetchone()[0]
        return [job_row(r) for r in rows], count

    def give_owner(self, old: str, new: str) -> int:
        """Every job of the token hash `old` now belongs to `new` (a student's replaced link); how many."""
        return self.db.execute("UPDATE jobs SET owner = ? WHERE owner = ?", (new, old)).rowcount

    def place(self, row: JobRow) -> dict:
        """A queued job's place: the queued jobs that a worker takes before it (its lane's order: lane,
        priority, age) and their estimated seconds; the running jobs it waits for (an interactive job:
        the interactive ones) and their estimated seconds left."""
        rank = LANE_RANK[Lane(row["lane"])]
        ahead = self.db.execute(
            f"SELECT COUNT(*), COALESCE(SUM(COALESCE(estimate, 0)), 0) FROM jobs WHERE status = ? AND"
            f" ({LANE_ORDER} < ? OR ({LANE_ORDER} = ? AND (priority > ? OR (priority = ? AND"
            " (created_at < ? OR (created_at = ? AND rowid < (SELECT rowid FROM jobs WHERE id = ?)))))))",
            (QUEUED, rank, rank, row["priority"], row["priority"], row["created_at"], row["created_at"], row["id"]),
        ).fetchone()
        # an interactive job waits for the running interactive jobs only: a batch render gives way to it
        # at its next pass
        lanes = (Lane.interactive.value,) if rank == 0 else (Lane.interactive.value, Lane.batch.value)
        running = self.db.execute(
            "SELECT COUNT(*), COALESCE(SUM(COALESCE(estimate, 0) * (1.0 - CASE WHEN samples_total > 0"
            " THEN MIN(1.0, samples_done * 1.0 / samples_total) ELSE 0 END)), 0) FROM jobs WHERE status = ?"
            f" AND lane IN ({', '.join('?' * len(lanes))}) AND id != ?",
            (RUNNING, *lanes, row["id"]),  # never itself: a worker may have taken it since `row` was read
        ).fetchone()
        return {"ahead": ahead[0], "ahead_seconds": ahead[1], "running": running[0], "running_seconds": running[1]}

    def pace(self, recent: int = 50) -> float:
        """How long renders take against their estimates: the median of (render seconds / estimate) of the
        last `recent` finished renders, clamped to [0.1, 10]; 1 with none yet."""
        rows = self.db.execute(
            "SELECT (finished_at - started_at) / estimate FROM jobs WHERE status = ? AND kind = ? AND estimate > 0"
            " AND started_at IS NOT NULL AND finished_at IS NOT NULL ORDER BY finished_at DESC LIMIT ?",
            (JobStatus.done.value, JobKind.render.value, recent),
        ).fetchall()
        ratios = sorted(r[0] for r in rows if r[0] is not None and r[0] > 0)
        if not ratios:
            return 1.0
        return float(min(10.0, max(0.1, ratios[len(ratios) // 2])))

    def counts(self) -> dict[str, int]:
        out = {s.value: 0 for s in JobStatus}
        for status, n in self.db.execute("SELECT status, COUNT(*) FROM jobs GROUP BY status"):
            out[status] = n
        return out

    def lanes(self) -> dict[str, dict[str, int]]:
        """The queued and running jobs of each lane (the status page)."""
        out = {lane.value: {"queued": 0, "running": 0} for lane in LANES}
        rows = self.db.execute(
            "SELECT lane, status, COUNT(*) FROM jobs WHERE status IN (?, ?) GROUP BY lane, status", (QUEUED, RUNNING)
        )
        for lane, status, n in rows:
            out.setdefault(lane, {"queued": 0, "running": 0})[status] = n
        return out

    def cancel(self, job_id: str) -> JobRowWithScene | None:
        """Cancel a queued job now; ask the worker of a running one to stop. The job's row after: cancelled
        (it was queued), running (asked to stop: however its try ends, it ends cancelled, see `finish`),
        or done or failed (it had ended first: nothing changed)."""
        with self._tx() as db:
            self._move(db, QUEUED, CANCELLED, "id = ?", (job_id,), error="cancelled before it started")
            db.execute("UPDATE jobs SET cancel_requested = 1 WHERE id = ? AND status = ?", (job_id, RUNNING))
            row = db.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return job_row(row) if row is not None else None

    def recover(self) -> tuple[int, int]:
        """At start-up: jobs left running by a dead server go back to the queue (or end, if cancelled)."""
        with self._tx() as db:
            error = "cancelled (the server stopped while it rendered)"
            cancelled = self._move(db, RUNNING, CANCELLED, "cancel_requested = 1", worker=None, error=error)
            requeued = self._move(db, RUNNING, QUEUED, worker=None)
        return len(requeued), len(cancelled)

    # -- the janitor --------------------------------------------------------------------------

    def finished_before(self, when: float) -> list[str]:
        """Ids of the jobs that finished (done, failed, cancelled) before Unix time `when`, first ended first."""
        rows = self.db.execute(
            f"SELECT id FROM jobs WHERE {FINISHED_IN} AND COALESCE(finished_at, created_at) < ?"
            " ORDER BY COALESCE(finished_at, created_at), rowid",
            (*FINISHED, when),
        ).fetchall()
        return [r["id"] for r in rows]

    def remove(self, job_id: str) -> bool:
        """Remove a finished job: its row, then its folder. Never a queued or running one (False)."""
        cur = self.db.execute(f"DELETE FROM jobs WHERE id = ? AND {FINISHED_IN}", (job_id, *FINISHED))
        if cur.rowcount == 0:
            return False
        self.remove_folder(job_id)
        return True

    def remove_folder(self, job_id: str) -> None:
        if looks_like_job_id(job_id):  # never a path built from anything else
            shutil.rmtree(self.job_dir(job_id), ignore_errors=True)

    def ids(self) -> set[str]:
        return {row["id"] for row in self.db.execute("SELECT id FROM jobs")}

    def job_folders(self) -> list[str]:
        """Names of the job folders on disk (the janitor removes those whose row is gone)."""
        try:
            return [e.name for e in os.scandir(self.jobs_dir) if e.is_dir(follow_symlinks=False)]
        except FileNotFoundError:
            return []
