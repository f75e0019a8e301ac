"""The facts of a running server that its operator watches (GET /api/status and the page /status, docs/service.md
"The status page"), those that live in the data directory and the settings: the release and the database's schema,
the last backup, and the disk. The queue's and the LMS's facts are their own packages'; server/api/routes/status.py
puts them together.

- **The last backup.** `python -m server backup` (server/core/backup.py) leaves `last-backup.json` in the data
  directory when it has written a whole backup: its time (UTC), where it went, its size. A backup is old past
  `BACKUP_OLD_SECONDS` (the nightly timer of deploy/ missed a night and then some).
- **The disk.** The data directory's size as the janitor last measured it (server/jobs/janitor.py, every
  TRACER_JANITOR_INTERVAL) against TRACER_MAX_DATA_BYTES (0: no limit), and the free space of its file system.
"""

from __future__ import annotations

import json
import logging
import shutil
import sqlite3
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

from server.core.files import write_atomic
from server.core.migrations import LATEST, schema_version
from server.core.startup import DB_NAME

log = logging.getLogger(__name__)

LAST_BACKUP = "last-backup.json"  # in the data directory: the last whole backup's time, place and size
BACKUP_OLD_SECONDS = 2 * 86400  # a nightly backup older than this is late: the page warns
DISK_NEAR = 0.9  # a data directory past this share of TRACER_MAX_DATA_BYTES: the page warns
PACKAGE = "raytrace-edu"


def version() -> str:
    """This release's version (the installed package's; pyproject.toml's where it is not installed)."""
    try:
        return metadata.version(PACKAGE)
    except metadata.PackageNotFoundError:
        text = (Path(__file__).resolve().parents[2] / "pyproject.toml").read_text()
        return next((line.split("=", 1)[1].strip().strip('"') for line in text.splitlines()
                     if line.startswith("version")), "unknown")  # fmt: skip


def schema(data_dir: Path) -> dict:
    """The database's schema version and this release's (`latest`); equal once the server has started."""
    db = sqlite3.connect(f"file:{Path(data_dir) / DB_NAME}?mode=ro", uri=True, timeout=5)
    try:
        return {"version": schema_version(db), "latest": LATEST}
    finally:
        db.close()


def record_backup(data_dir: Path, dest: Path, manifest: dict) -> None:
    """What a finished backup leaves in the data directory it copied (for the status page); a failure to write
    it is logged, never the backup's failure."""
    size = manifest["database"]["bytes"] + sum(f["bytes"] for f in manifest["files"].values())
    record = {"time": manifest["time"], "dest": str(Path(dest).resolve()), "bytes": size,
              "files": manifest["file_count"]}  # fmt: skip
    try:
        write_atomic(Path(data_dir) / LAST_BACKUP, lambda tmp: tmp.write_text(json.dumps(record, indent=1) + "\n"))
    except OSError as e:
        log.warning("the backup is whole, but its record for the status page was not written: %s", e)


def last_backup(data_dir: Path, now: datetime) -> dict:
    """The last backup: `time` (None: none recorded), `age_seconds`, `dest`, `bytes`, and `old` (none, or older
    than BACKUP_OLD_SECONDS)."""
    try:
        record = json.loads((Path(data_dir) / LAST_BACKUP).read_text())
        taken = datetime.fromisoformat(record["time"]).astimezone(UTC)
    except (FileNotFoundError, ValueError, KeyError, TypeError):
        return {"time": None, "age_seconds": None, "dest": None, "bytes": None, "old": True}
    age = max(0.0, (now - taken).total_seconds())
    return {"time": taken.isoformat(), "age_seconds": age, "dest": record.get("dest"), "bytes": record.get("bytes"),
            "old": age > BACKUP_OLD_SECONDS}  # fmt: skip


def disk(data_dir: Path, used: int | None, measured_at: datetime | None, limit: int) -> dict:
    """The data directory's `used_bytes` (None before the janitor's first round) against `limit_bytes` (0: none),
    its `share` of it, the file system's `free_bytes`, and `near` (past DISK_NEAR of the limit)."""
    share = used / limit if used is not None and limit > 0 else None
    try:
        free = shutil.disk_usage(data_dir).free
    except OSError:
        free = None
    return {"used_bytes": used, "limit_bytes": limit, "share": share, "free_bytes": free,
            "measured_at": measured_at.isoformat() if measured_at else None,
            "near": share is not None and share >= DISK_NEAR}  # fmt: skip
