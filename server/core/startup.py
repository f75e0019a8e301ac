"""Checks of the data directory before the server starts, each answered with what is wrong and what to do.

`python -m server` runs them before it serves anything (and the app's lifespan for a server started
another way); a problem is one message on stderr and a non-zero exit status, never a traceback, and
nothing in the data directory is changed or removed:

- the data directory is a file, cannot be made, or is read-only (a real write is tried: root ignores
  mode bits, a read-only mount does not);
- jobs/ is not a folder;
- the job database (jobs.sqlite3) is damaged: not an SQLite file, or `PRAGMA quick_check` finds broken
  pages (a truncated file);
- the job database is missing or new (an empty file, or one without the jobs table) while jobs/ holds
  job folders: their rows are gone, and the janitor would remove the folders as orphans. The server
  refuses to start rather than drop them: a job's folder holds its images but not its scene or status,
  so the jobs cannot be adopted back from it.

Then `lock_data_dir` takes the data directory's lock (DATA/server.lock): one server per data directory, and no
restore into one a server uses.
"""

from __future__ import annotations

import fcntl
import os
import sqlite3
import tempfile
from pathlib import Path

from server.core.files import make_private, private_files
from server.core.ids import looks_like_job_id

DB_NAME = "jobs.sqlite3"


class StartupError(RuntimeError):
    """The server cannot start on this data directory: the message says why and what to do."""


def check_data_dir(data_dir: Path) -> None:
    """Raise StartupError if the server cannot run on `data_dir` (creating it when it is missing, 0700). From here
    on, what the process makes is private to its user (server/core/files.py, `private_files`)."""
    data_dir = Path(data_dir)
    private_files()
    where = f"the data directory {data_dir} (--data-dir, TRACER_DATA_DIR)"
    if data_dir.exists() and not data_dir.is_dir():
        raise StartupError(f"{where} is a file, not a folder: give a folder (it is made if it is missing)")
    try:
        data_dir.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as e:
        raise StartupError(f"cannot make {where}: {e.strerror}; make it yourself or give another folder") from None
    try:
        with tempfile.TemporaryFile(dir=data_dir, prefix=".write-check-"):
            pass
    except OSError as e:
        raise StartupError(
            f"{where} is not writable ({e.strerror}): the server keeps its job database and images there. Make "
            "it writable (a read-only mount: remount it read-write) or give another folder"
        ) from None
    for name in (DB_NAME, f"{DB_NAME}-wal", f"{DB_NAME}-shm"):  # an earlier release's, made 0644
        make_private(data_dir / name)
    jobs = data_dir / "jobs"
    if jobs.exists() and not jobs.is_dir():
        raise StartupError(f"{jobs} is a file; the server keeps each job's files in that folder: move the file away")
    check_database(data_dir)


def job_folders(data_dir: Path) -> list[str]:
    """The names of the job folders in DATA/jobs/."""
    try:
        return [e.name for e in os.scandir(data_dir / "jobs") if e.is_dir() and looks_like_job_id(e.name)]
    except FileNotFoundError:
        return []


def check_database(data_dir: Path) -> None:
    """The job database is whole (PRAGMA quick_check), and holds the jobs whose folders are in jobs/."""
    path = data_dir / DB_NAME
    folders = job_folders(data_dir)
    orphans = (
        f"{len(folders)} job folder(s) in {data_dir / 'jobs'} belong to jobs it does not hold, and starting would "
        "lose them (their scenes and statuses were in the database; the janitor removes folders without a job). "
        "Restore jobs.sqlite3 from a backup; or, to start afresh, move the data directory away and start on a new "
        "one. Nothing was changed"
    )
    if not path.exists():
        if folders:
            raise StartupError(f"{path} is missing: {orphans}")
        return
    damaged = (
        f"the job database {path} is damaged ({{}}). Restore it from a backup; or, to start afresh, move the data "
        "directory away and start on a new one (its jobs/ folder keeps the images). Nothing was changed"
    )
    try:
        conn = sqlite3.connect(f"file:{path}?mode=rw", uri=True, timeout=30, isolation_level=None)
    except sqlite3.Error as e:
        raise StartupError(damaged.format(e)) from None
    try:
        problems = [row[0] for row in conn.execute("PRAGMA quick_check(5)")]
        if problems != ["ok"]:
            raise StartupError(damaged.format("; ".join(problems)))
        tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    except sqlite3.DatabaseError as e:  # "file is not a database", "database disk image is malformed"
        raise StartupError(damaged.format(e)) from None
    finally:
        conn.close()
    if "jobs" not in tables and folders:
        state = "an empty file" if path.stat().st_size == 0 else "a database without the jobs table"
        raise StartupError(f"{path} is {state}: {orphans}")


def lock_data_dir(data_dir: Path):
    """One server per data directory: a second would take the first one's running jobs back. The lock is
    held while the returned file is open (a restore takes it too: it refuses a directory a server uses)."""
    lock = open(Path(data_dir) / "server.lock", "a")  # noqa: SIM115 (held open while the server runs)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        raise StartupError(
            f"another server is using the data directory {data_dir}: stop it, or give this one another folder"
        ) from None
    return lock


OWN_FILES = 512  # files the server holds open besides its connections: databases and their WAL, pipes, workers
FILES_PER_CONNECTION = 2  # its socket, and a file its request may write (a submission, a job's scene)


def raise_open_files(connections: int) -> tuple[int, int, int]:
    """Raise this process's soft limit of open files towards its hard limit, enough for `connections` open
    connections (TRACER_MAX_CONNECTIONS) and the server's own files: (the soft limit before, after, the
    connections it leaves room for: `connections`, or fewer where the hard limit is too low).

    A service manager starts a process with a soft limit of 1 024 (systemd's default, whatever its hard limit),
    and each connection, event stream and file a request writes takes one: a class of 1 000 submitting at once
    got 210 answers 500 ("too many open files") at that limit. As Go's runtime and nginx do, the soft limit is
    raised, never past the hard one (raising that is the deployer's: LimitNOFILE=, docs/service.md); below
    it, the server takes fewer connections at once (503 past them, which a client may retry) rather than fail
    the requests it took."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = connections * FILES_PER_CONNECTION + OWN_FILES
    if soft == resource.RLIM_INFINITY or soft >= want:
        return soft, soft, connections
    target = want if hard == resource.RLIM_INFINITY else min(want, hard)
    resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
    return soft, target, min(connections, max(1, (target - OWN_FILES) // FILES_PER_CONNECTION))
