"""Files on the data directory's disk: private to the server's user (the folder 0700, each file 0600), written
whole (a reader sees the old file or the new one), and a full disk told apart from other errors (the service
answers 507 and lives on)."""

from __future__ import annotations

import errno
import os
import sqlite3
import threading
from pathlib import Path

PRIVATE_UMASK = 0o077  # what the server's process makes is its user's alone: folders 0700, files 0600
PRIVATE_FILE = 0o600


def private_files() -> None:
    """From now on, what this process makes is private to its user (umask 077): the database and its WAL, the
    job images, submissions, grading runs' files, backups. They hold students' work and names; a data directory
    on a shared machine must not be readable by its other users (issue #39, item 12). Set by `python -m server`
    and its upkeep commands, and by the app's start-up, before anything is made."""
    os.umask(PRIVATE_UMASK)


def make_private(path: Path) -> None:
    """A file made before `private_files` (a data directory of an earlier release): its mode tightened to 0600."""
    try:
        if path.stat().st_mode & 0o077:
            os.chmod(path, PRIVATE_FILE)
    except FileNotFoundError:
        pass


def is_disk_full(exc: BaseException) -> bool:
    """Is `exc` a full disk (or quota): an OSError ENOSPC or EDQUOT, or SQLite's "database or disk is full"?"""
    if isinstance(exc, OSError):
        return exc.errno in (errno.ENOSPC, errno.EDQUOT)
    if isinstance(exc, sqlite3.Error):
        return getattr(exc, "sqlite_errorcode", None) == sqlite3.SQLITE_FULL or "disk is full" in str(exc)
    return False


def write_atomic(path: Path, write) -> None:
    """`write(tmp_path)`, then rename onto `path`: readers see the old file or the new one, never half of one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{os.getpid()}.{threading.get_ident()}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
