"""The job store's base (server/jobs/store.py): the jobs table made (or an older one given its new columns),
each thread's connection, and the moves of the life cycle (`_move`) with the SQL they write: a try begun or
ended, the fence a writer must match (an embedded worker's pid, or a try's `Attempt`).

Statuses change only through `_move`, one UPDATE per move of the life cycle (server/jobs/lifecycle.py):
its WHERE names the status the job leaves, so a move that lost a race changes nothing."""

from __future__ import annotations

import socket
import sqlite3
import threading
import time
from pathlib import Path

from server.core.db import Transaction, close_all, thread_connection
from server.jobs.lifecycle import FINISHED, LANE_RANK, LANES, JobStatus, check_transition
from server.jobs.rows import SCHEMA, JobRowWithScene, job_row

QUEUED, RUNNING, FAILED, CANCELLED = JobStatus.queued, JobStatus.running, JobStatus.failed, JobStatus.cancelled
HOST = socket.gethostname()  # the embedded workers' host: this one
_WHEN = " ".join(f"WHEN '{lane}' THEN {rank}" for lane, rank in LANE_RANK.items())
LANE_ORDER = f"CASE lane {_WHEN} ELSE {len(LANES)} END"  # SQL: the lanes in the order workers take them
FINISHED_IN = f"status IN ({', '.join('?' * len(FINISHED))})"  # SQL: the job has ended (args: *FINISHED)


class Sql:
    """A field's new value given as an SQL expression (`attempts + 1`), written into the statement,
    with its own bound arguments."""

    def __init__(self, sql: str, *args):
        self.sql, self.args = sql, args


class Attempt(int):
    """A writer that owns a job by its try number (the Redis backend: events of try k apply only while
    the job's `attempts` is still k). A plain int names an embedded worker by its pid."""


def fence(who: int | None) -> tuple[str, tuple]:
    """SQL (and args) that a running job's row must match for `who` to write it: an embedded worker's
    pid, a try's Attempt, or None (the supervisor: anyone)."""
    if who is None:
        return "", ()
    if isinstance(who, Attempt):
        return "attempts = ?", (int(who),)
    return "worker = ?", (who,)


def all_of(*parts: str) -> str:
    return " AND ".join(p for p in parts if p)


def begin_try(attempt: str, host: str | None, device: str | None, worker) -> Sql:
    """`tries` with a new try appended (its outcome null until it ends); `attempt` is SQL (the row's old
    values: `attempts + 1` is the try a claim begins)."""
    entry = (
        f"json_object('attempt', {attempt}, 'host', ?, 'device', ?, 'worker', ?, 'started_at', ?,"
        " 'ended_at', NULL, 'outcome', NULL, 'resumed_from', snapshot)"
    )
    return Sql(f"json_insert(tries, '$[#]', {entry})", host, device, worker, time.time())


def fresh_unless_resumed() -> dict[str, Sql]:
    """The progress fields a new try starts from: zero, or, resuming from a snapshot, as they were."""
    zero = {"samples_done": "0", "passes_done": "0", "spp_done": "0", "preview": "0", "rays": "'{}'"}
    return {k: Sql(f"CASE WHEN snapshot > 0 THEN {k} ELSE {v} END") for k, v in zero.items()}


def end_try(outcome: str) -> Sql:
    """`tries` with its last try ended: done, failed, cancelled, lost (with its worker), given back."""
    return Sql("json_set(tries, '$[#-1].ended_at', ?, '$[#-1].outcome', ?)", time.time(), outcome)


class JobTables:
    """The jobs table and its connections: the base of JobStore and of its mixins (server/jobs/worker_store.py,
    server/jobs/tries_store.py)."""

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
        sets = ", ".join(f"{k} = {v.sql}" if isinstance(v, Sql) else f"{k} = ?" for k, v in fields.items())
        values = [a for v in fields.values() for a in (v.args if isinstance(v, Sql) else (v,))]
        sql = f"UPDATE jobs SET {sets} WHERE status = ?" + (f" AND ({where})" if where else "") + " RETURNING *"
        return [job_row(r) for r in db.execute(sql, (*values, source.value, *args)).fetchall()]
