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
import socket
import sqlite3
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TypedDict, cast

from server.core.db import Transaction, close_all, thread_connection
from server.core.files import write_atomic
from server.core.ids import looks_like_job_id, new_job_id
from server.jobs.files import JobFile
from server.jobs.lifecycle import (
    FINISHED,
    LANE_RANK,
    LANES,
    BadTransition,
    JobKind,
    JobStatus,
    Lane,
    TryEnd,
    after_lost,
    check_transition,
    lost_error,
)

SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    id TEXT PRIMARY KEY,                    -- secrets.token_urlsafe: unguessable
    status TEXT NOT NULL,                   -- JobStatus
    priority INTEGER NOT NULL DEFAULT 0,    -- higher first
    created_at REAL NOT NULL,               -- Unix time (s)
    started_at REAL,                        -- when a worker took it (latest attempt)
    finished_at REAL,
    name TEXT,                              -- the scene's name
    scene TEXT NOT NULL,                    -- the scene JSON, as submitted
    warnings TEXT NOT NULL DEFAULT '[]',    -- [{path, message}] from validation
    width INTEGER NOT NULL,
    height INTEGER NOT NULL,
    spp INTEGER NOT NULL,
    max_seconds REAL NOT NULL,              -- render time limit of this job
    samples_done INTEGER NOT NULL DEFAULT 0, -- the renderer's progress units (pixel samples; adaptive: pixel passes)
    samples_total INTEGER NOT NULL,
    passes_done INTEGER NOT NULL DEFAULT 0,
    spp_done INTEGER NOT NULL DEFAULT 0,
    rays TEXT NOT NULL DEFAULT '{}',        -- rays by kind, as of the latest pass
    preview INTEGER NOT NULL DEFAULT 0,     -- pass number of the image on disk (0 = none)
    error TEXT,                             -- why it failed or stopped
    errors TEXT NOT NULL DEFAULT '[]',      -- scene errors found by the worker
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    attempts INTEGER NOT NULL DEFAULT 0,    -- times a worker took it
    worker INTEGER,                         -- pid of the embedded worker rendering it
    solve TEXT,                             -- the radiosity solve so far (JSON: fraction, shots, rays, ...)
    host TEXT,                              -- the worker host (name) of the latest try
    device TEXT,                            -- the device the latest try renders on (cpu, cuda:0)
    lost INTEGER NOT NULL DEFAULT 0,        -- tries lost with their worker (a crash, a dead or cut-off host)
    tries TEXT NOT NULL DEFAULT '[]',       -- each try: {attempt, host, device, worker, started_at, ended_at, outcome}
    kind TEXT NOT NULL DEFAULT 'render',    -- JobKind: render, raytree
    lane TEXT NOT NULL DEFAULT 'interactive', -- Lane: interactive first, then batch
    params TEXT NOT NULL DEFAULT '{}',      -- a ray tree's {x, y, sample}
    estimate REAL,                          -- seconds the render was estimated to take on one worker
    snapshot INTEGER NOT NULL DEFAULT 0,    -- the pass of the film saved in the job's snapshot file (0: none)
    owner TEXT,                             -- SHA-256 (hex) of the token that made it; NULL: the instructor's
    result_key TEXT,                        -- a render's pixels' key (server/jobs/results.py); NULL: not answered again
    answered_from TEXT                      -- the done job whose files answered this one at submit (NULL: rendered)
);
"""


class JobRow(TypedDict):
    """A job's row as the store returns it (SCHEMA's columns, JSON ones as their text), its scene left out
    (`peek`, `rows`: the scene may be megabytes): what the job service, the queues and `JobPublic.from_row` read,
    so that the type checker knows its keys. `JobRowWithScene`: the whole row (`get`, `SELECT *`)."""

    id: str
    status: str  # a JobStatus
    priority: int
    created_at: float
    started_at: float | None
    finished_at: float | None
    name: str | None
    warnings: str  # JSON: [{path, message}]
    width: int
    height: int
    spp: int
    max_seconds: float
    samples_done: int
    samples_total: int
    passes_done: int
    spp_done: int
    rays: str  # JSON: {kind: count}
    preview: int
    error: str | None
    errors: str  # JSON: [{path, message}]
    cancel_requested: int
    attempts: int
    worker: int | None
    solve: str | None  # JSON
    host: str | None
    device: str | None
    lost: int
    tries: str  # JSON: [{attempt, host, device, worker, started_at, ended_at, outcome}]
    kind: str  # a JobKind
    lane: str  # a Lane
    params: str  # JSON
    estimate: float | None
    snapshot: int
    owner: str | None
    result_key: str | None
    answered_from: str | None


class JobRowWithScene(JobRow):
    scene: str  # the scene JSON, as submitted


def job_row(row: sqlite3.Row) -> JobRowWithScene:
    """A row of `SELECT *` from the jobs table, typed."""
    return cast(JobRowWithScene, dict(row))


def job_row_sceneless(row: sqlite3.Row) -> JobRow:
    """A row of every column but the scene (`JobStore._sceneless`), typed."""
    return cast(JobRow, dict(row))


QUEUED, RUNNING, FAILED, CANCELLED = JobStatus.queued, JobStatus.running, JobStatus.failed, JobStatus.cancelled
HOST = socket.gethostname()  # the embedded workers' host: this one
_WHEN = " ".join(f"WHEN '{lane}' THEN {rank}" for lane, rank in LANE_RANK.items())
LANE_ORDER = f"CASE lane {_WHEN} ELSE {len(LANES)} END"  # SQL: the lanes in the order workers take them
FINISHED_IN = f"status IN ({', '.join('?' * len(FINISHED))})"  # SQL: the job has ended (args: *FINISHED)


class _Sql:
    """A field's new value given as an SQL expression (`attempts + 1`), written into the statement,
    with its own bound arguments."""

    def __init__(self, sql: str, *args):
        self.sql, self.args = sql, args


class Attempt(int):
    """A writer that owns a job by its try number (the Redis backend: events of try k apply only while
    the job's `attempts` is still k). A plain int names an embedded worker by its pid."""


def _fence(who: int | None) -> tuple[str, tuple]:
    """SQL (and args) that a running job's row must match for `who` to write it: an embedded worker's
    pid, a try's Attempt, or None (the supervisor: anyone)."""
    if who is None:
        return "", ()
    if isinstance(who, Attempt):
        return "attempts = ?", (int(who),)
    return "worker = ?", (who,)


def _and(*parts: str) -> str:
    return " AND ".join(p for p in parts if p)


def _begin_try(attempt: str, host: str | None, device: str | None, worker) -> _Sql:
    """`tries` with a new try appended (its outcome null until it ends); `attempt` is SQL (the row's old
    values: `attempts + 1` is the try a claim begins)."""
    entry = (
        f"json_object('attempt', {attempt}, 'host', ?, 'device', ?, 'worker', ?, 'started_at', ?,"
        " 'ended_at', NULL, 'outcome', NULL, 'resumed_from', snapshot)"
    )
    return _Sql(f"json_insert(tries, '$[#]', {entry})", host, device, worker, time.time())


def _fresh_unless_resumed() -> dict[str, _Sql]:
    """The progress fields a new try starts from: zero, or, resuming from a snapshot, as they were."""
    zero = {"samples_done": "0", "passes_done": "0", "spp_done": "0", "preview": "0", "rays": "'{}'"}
    return {k: _Sql(f"CASE WHEN snapshot > 0 THEN {k} ELSE {v} END") for k, v in zero.items()}


def _end_try(outcome: str) -> _Sql:
    """`tries` with its last try ended: done, failed, cancelled, lost (with its worker), given back."""
    return _Sql("json_set(tries, '$[#-1].ended_at', ?, '$[#-1].outcome', ?)", time.time(), outcome)


class QueueFull(Exception):
    """The queue is full (`args`: the jobs waiting, and "owner" when it is the owner's share that is; or the owner's
    renders waiting or running, and "active", when the owner has their fair share of the workers)."""


class JobStore:
    def __init__(self, data_dir: Path):
        self.data_dir = Path(data_dir)
        self.jobs_dir = self.data_dir / "jobs"
        self.db_path = self.data_dir / "jobs.sqlite3"
        self._local = threading.local()
        self._quick = threading.local()  # `peek`'s connections: they never wait for a lock
        self._opened: list = []  # every thread's connections (close)
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        self.db.executescript(SCHEMA)
        self._add_columns()

    def _add_columns(self) -> None:
        """Columns added since a data dir was made: an older database gets them (empty)."""
        have = {row["name"] for row in self.db.execute("PRAGMA table_info(jobs)")}
        added = (
            ("solve", "TEXT"),
            ("host", "TEXT"),
            ("device", "TEXT"),
            ("lost", "INTEGER NOT NULL DEFAULT 0"),
            ("tries", "TEXT NOT NULL DEFAULT '[]'"),
            ("kind", "TEXT NOT NULL DEFAULT 'render'"),
            ("lane", "TEXT NOT NULL DEFAULT 'interactive'"),
            ("params", "TEXT NOT NULL DEFAULT '{}'"),
            ("estimate", "REAL"),
            ("snapshot", "INTEGER NOT NULL DEFAULT 0"),
            ("owner", "TEXT"),  # older rows: no owner, the instructor's (server/core/security.py)
            ("result_key", "TEXT"),
            ("answered_from", "TEXT"),
        )
        for name, decl in added:
            if name not in have:
                self.db.execute(f"ALTER TABLE jobs ADD COLUMN {name} {decl}")
        self.db.execute("DROP INDEX IF EXISTS jobs_queue")  # the claim order: lane, priority, age
        self.db.execute("CREATE INDEX IF NOT EXISTS jobs_claim ON jobs (status, lane, priority DESC, created_at)")
        self.db.execute("CREATE INDEX IF NOT EXISTS jobs_owner ON jobs (owner, created_at)")  # a student's list
        self.db.execute("CREATE INDEX IF NOT EXISTS jobs_result ON jobs (result_key, status)")  # a render again

    # -- connections --------------------------------------------------------------------------

    @property
    def db(self) -> sqlite3.Connection:
        return thread_connection(self._local, self.db_path, opened=self._opened)

    def close_connections(self) -> None:
        """Every thread's connection closed (the app stops; the store is not used after)."""
        close_all(self._opened)

    def _tx(self):
        return Transaction(self.db)

    def _one(self, sql: str, args=()) -> dict | None:
        row = self.db.execute(sql, args).fetchone()
        return dict(row) if row is not None else None

    def _job(self, sql: str, args=()) -> JobRowWithScene | None:
        """One job's whole row (`SELECT *`), or None."""
        row = self.db.execute(sql, args).fetchone()
        return job_row(row) if row is not None else None

    # -- moves of the life cycle --------------------------------------------------------------

    def _move(
        self,
        db: sqlite3.Connection,
        source: JobStatus,
        target: JobStatus,
        where: str = "",
        args: tuple = (),
        **fields,
    ) -> list[JobRowWithScene]:
        """Move the jobs in status `source` that match `where` (SQL, with `args`) to `target`, setting
        `fields` too (values bound, or _Sql expressions); a move into a finished status stamps
        `finished_at`. Returns the rows moved, as they are after the move."""
        check_transition(source, target)
        if target.finished:
            fields.setdefault("finished_at", time.time())
        fields = {"status": target.value, **fields}
        sets = ", ".join(f"{k} = {v.sql}" if isinstance(v, _Sql) else f"{k} = ?" for k, v in fields.items())
        values = [a for v in fields.values() for a in (v.args if isinstance(v, _Sql) else (v,))]
        sql = f"UPDATE jobs SET {sets} WHERE status = ?" + (f" AND ({where})" if where else "") + " RETURNING *"
        return [job_row(r) for r in db.execute(sql, (*values, source.value, *args)).fetchall()]

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
                           lost=_Sql("lost + 1"), tries=_end_try(TryEnd.lost))  # fmt: skip
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
                attempts=_Sql("attempts + 1"), error=None, host=HOST, device="cpu",
                **_fresh_unless_resumed(), tries=_begin_try("attempts + 1", HOST, "cpu", pid),
            )  # fmt: skip
        return rows[0] if rows else None

    def control(self, job_id: str, who: int) -> dict | None:
        """What a worker checks between bands: is the job still its own (None if not), and is a stop requested."""
        where, args = _fence(who)
        return self._one(f"SELECT cancel_requested FROM jobs WHERE {_and('id = ?', where, 'status = ?')}",
                         (job_id, *args, RUNNING))  # fmt: skip

    def progress(self, job_id: str, who: int, **fields) -> bool:
        """Update progress fields (samples_done, samples_total, passes_done, spp_done, rays, preview, solve) of
        its job, while `who` (a worker's pid, or a try's Attempt) still has it."""
        for key in ("rays", "solve"):
            if key in fields:
                fields[key] = json.dumps(fields[key])
        sets = ", ".join(f"{k} = ?" for k in fields)
        where, args = _fence(who)
        cur = self.db.execute(
            f"UPDATE jobs SET {sets} WHERE {_and('id = ?', where, 'status = ?')}",
            (*fields.values(), job_id, *args, RUNNING),
        )
        return cur.rowcount > 0

    def requeue(self, job_id: str, who: int, outcome: TryEnd = TryEnd.given_back) -> JobStatus | None:
        """Give a job back to the queue: its worker is shutting down (given back), or its render gives
        way to interactive work (gave way). An embedded worker's try does not count (the next claim
        counts it again); a try of the Redis backend is given back as the next try (tries are its
        fence), which counts nothing lost either. A job whose cancel was accepted ends cancelled
        instead. The status it moved to (queued or cancelled), or None if `who` no longer had it."""
        where, args = _fence(who)
        again = _Sql("attempts + 1") if isinstance(who, Attempt) else _Sql("MAX(attempts - 1, 0)")
        with self._tx() as db:
            if self._move(
                db, RUNNING, CANCELLED, _and("id = ?", where, "cancel_requested = 1"), (job_id, *args),
                worker=None, error=f"cancelled (its try was {outcome})", tries=_end_try(CANCELLED.value),
            ):  # fmt: skip
                return CANCELLED  # a cancel accepted while it ran wins: its client was told it ends cancelled
            moved = self._move(
                db, RUNNING, QUEUED, _and("id = ?", where), (job_id, *args),
                worker=None, attempts=again, tries=_end_try(outcome),
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
        where, args = _fence(who)
        mine = (_and("id = ?", where), (job_id, *args))
        with self._tx() as db:
            if status is not CANCELLED:  # a cancel accepted while it ran (202) wins, whatever the try's end
                error = f"cancelled ({fields['error']})" if fields.get("error") else "cancelled while rendering"
                cancelled = {**fields, "error": error, "tries": _end_try(CANCELLED.value)}
                if self._move(db, RUNNING, CANCELLED, _and(mine[0], "cancel_requested = 1"), mine[1], **cancelled):
                    return True
            fields.setdefault("tries", _end_try(status.value))
            return bool(self._move(db, RUNNING, status, *mine, **fields))

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
            worker=None, started_at=time.time(), finished_at=None, **_fresh_unless_resumed(), error=None,
            host=host, device=device,
            tries=_begin_try("attempts", host, device, worker),
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
            end = _end_try(TryEnd.lost) if source is RUNNING else _Sql("tries")
            status = after_lost(row["lost"], max_tries, bool(row["cancel_requested"]))
            if status is not QUEUED:
                error = f"cancelled ({reason})" if status is CANCELLED else lost_error(reason, attempt)
                self._move(db, source, status, "id = ?", (job_id,), error=error, lost=_Sql("lost + 1"), tries=end)
                return status.value, attempt
            if source is RUNNING:
                self._move(db, RUNNING, QUEUED, "id = ?", (job_id,), attempts=_Sql("attempts + 1"),
                           lost=_Sql("lost + 1"), tries=end)  # fmt: skip
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
