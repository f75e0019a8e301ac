"""Files on the data directory's disk: written whole (a reader sees the old file or the new one), and a
full disk told apart from other errors (the service answers 507 and lives on)."""

from __future__ import annotations

import errno
import os
import sqlite3
import threading
from pathlib import Path


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
