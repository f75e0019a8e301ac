"""SQLite as the service uses it: one connection per thread and process (WAL, a busy timeout), and
transactions that never leave a connection inside one (the job store and the grading store share them)."""

from __future__ import annotations

import os
import sqlite3
import threading
from pathlib import Path


def thread_connection(
    local: threading.local, db_path: Path, busy_ms: int = 30000, opened: list | None = None
) -> sqlite3.Connection:
    """This thread's connection to the database, kept in `local` (a new one in another process: a connection
    never crosses a fork): autocommit (transactions are `Transaction`s), WAL, waiting up to `busy_ms` for a
    lock (30 s; 0 for a read that must never wait, which raises sqlite3.OperationalError instead). A new one is
    also added to `opened`, so that its owner can close every thread's connection when it stops (`close_all`:
    a thread of a pool outlives the app, and its connection would keep two files open)."""
    conn = getattr(local, "conn", None)
    if conn is None or getattr(local, "pid", None) != os.getpid():
        # used by one thread only; another may close it (close_all, when every thread has stopped using it)
        conn = sqlite3.connect(db_path, timeout=busy_ms / 1000, isolation_level=None, check_same_thread=False)
        conn.row_factory = sqlite3.Row
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=NORMAL")
        conn.execute(f"PRAGMA busy_timeout={int(busy_ms)}")
        local.conn, local.pid = conn, os.getpid()
        if opened is not None:
            opened.append((os.getpid(), conn))
    return conn


def close_all(opened: list) -> None:
    """Close the connections `thread_connection` opened into `opened` in this process (a store's, when the app
    that used it stops); those a forked process inherited are left to it."""
    pid = os.getpid()
    for owner, conn in opened[:]:
        if owner == pid:
            try:
                conn.close()
            except sqlite3.Error:
                pass
    opened.clear()


class Transaction:
    """`with`: BEGIN IMMEDIATE ... COMMIT (ROLLBACK on an exception), on an autocommit connection. A COMMIT
    that fails (the disk full) rolls back too, so the connection is never left inside a transaction: the
    next one begins cleanly once there is space again."""

    def __init__(self, conn: sqlite3.Connection):
        self.conn = conn

    def __enter__(self) -> sqlite3.Connection:
        self.conn.execute("BEGIN IMMEDIATE")
        return self.conn

    def __exit__(self, kind, value, tb) -> None:
        if kind is None:
            try:
                self.conn.execute("COMMIT")
                return
            except BaseException:
                self._rollback()
                raise
        self._rollback()

    def _rollback(self) -> None:
        if self.conn.in_transaction:  # SQLite may have rolled it back itself (a full disk, an I/O error)
            try:
                self.conn.execute("ROLLBACK")
            except sqlite3.Error:
                pass


class Tables:
    """Tables of the data directory's database (DATA/jobs.sqlite3: the jobs', the grading runs', the
    course's): `schema` made if new, this thread's connection (`db`), transactions (`_tx`)."""

    def __init__(self, data_dir: Path, schema: str):
        self.db_path = Path(data_dir) / "jobs.sqlite3"
        self._local = threading.local()
        self._opened: list = []  # every thread's connection (close)
        self.db.executescript(schema)

    @property
    def db(self) -> sqlite3.Connection:
        return thread_connection(self._local, self.db_path, opened=self._opened)

    def close_connections(self) -> None:
        """Every thread's connection closed (the app stops; a store is not used after)."""
        close_all(self._opened)

    def _tx(self) -> Transaction:
        return Transaction(self.db)
