"""Backups of a data directory, taken from a live server, and their restore (`python -m server backup DEST`,
`python -m server restore SRC`: server/__main__.py; docs/service.md, "Backups and upgrades").

A backup is a folder:
- `jobs.sqlite3`: the database, copied through SQLite's online backup API in one read transaction (a
  consistent snapshot; the server's writers go on meanwhile, WAL mode). Never a plain copy of the file: a WAL
  database's file alone lacks the commits still in its -wal file, and a copy taken mid-write is torn;
- `files/`: every other file of the data directory (job images, grading runs' outputs in grades/, course
  submissions in course/, LTI keys in lti/, ...), copied AFTER the snapshot. A file is written before the row
  that names it (server/course/submissions.py: the file, then its row), so every file a row of the snapshot names
  was there to copy (unless the janitor removed an old job meanwhile). Files made after the snapshot come too;
  a server started on the restore removes what no row names (the janitor). Left out: what a server remakes
  (the radiosity cache, the examples' previews), its locks, half-written files (`.<pid>.<thread>.tmp...`, see
  server/core/files.py), and the copies of earlier upgrades in backups/;
- `manifest.json`, written last (a folder without it is an unfinished backup, and restore refuses it): the
  time (UTC), the schema version, the rows of each table, and the size and SHA-256 of the database and of each
  file.
  After it, `last-backup.json` in the data directory (the backup's time, place and size: what the status page
  shows, server/core/status.py); it is not backed up itself.

A restore checks every checksum before it writes anything, then copies into an empty (or new) data directory
under its lock (it refuses one a server holds, and a non-empty one unless `force`: then what was there goes),
and checks the database with `PRAGMA integrity_check`.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sqlite3
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

from server.core.files import is_disk_full
from server.core.migrations import BACKUPS, LOCK_NAME, backup_database, schema_version
from server.core.startup import DB_NAME, StartupError, lock_data_dir
from server.core.status import LAST_BACKUP, record_backup

MANIFEST = "manifest.json"
FILES = "files"  # the backup's copy of the data directory's files
# top-level names not backed up (the last backup's record is the data directory's own, not to be restored)
SKIPPED = {BACKUPS, "cache", "previews", "server.lock", LOCK_NAME, LAST_BACKUP}
CHUNK = 1 << 20  # bytes read at a time for a checksum


class BackupError(StartupError):
    """A backup or a restore cannot be done: the message says why and what to do."""


def utc_now() -> datetime:
    return datetime.now(UTC)


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(CHUNK):
            h.update(block)
    return h.hexdigest()


def _skipped(rel: Path) -> bool:
    top = rel.parts[0]
    return (
        top in SKIPPED
        or (len(rel.parts) == 1 and top.startswith(DB_NAME))  # the database, its -wal and -shm
        or rel.name.startswith(".")  # half-written (write_atomic's temporaries), checks of writability
    )


def backup(data_dir: Path, dest: Path, clock: Callable[[], datetime] = utc_now) -> dict:
    """Back up `data_dir` (a server may be running on it) into `dest`, a new or empty folder; the manifest."""
    data_dir, dest = Path(data_dir), Path(dest)
    db_path = data_dir / DB_NAME
    if not db_path.is_file():
        raise BackupError(f"{data_dir} holds no {DB_NAME}: is it a data directory (--data-dir, TRACER_DATA_DIR)?")
    for leftover in dest.glob(".*.partial") if dest.is_dir() else ():  # a killed backup's half-written files
        leftover.unlink(missing_ok=True)
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())):
        raise BackupError(f"{dest} is not an empty folder: give a new one (a backup never overwrites another)")
    made = not dest.exists()
    dest.mkdir(mode=0o700, parents=True, exist_ok=True)
    try:
        return _backup(data_dir, dest, clock)
    except BaseException as e:  # nothing is left behind: the same command can be run again
        if made:
            shutil.rmtree(dest, ignore_errors=True)
        else:
            for p in list(dest.iterdir()):
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() and not p.is_symlink() else p.unlink()
        if isinstance(e, (OSError, sqlite3.Error)) and is_disk_full(e):
            raise BackupError(
                f"the disk of {dest} is full ({e}): nothing of the backup was left there; free space (the backup "
                f"needs about {_size(data_dir)} bytes) and run the same command again"
            ) from None
        raise


def _size(data_dir: Path) -> int:
    """Bytes of what a backup of `data_dir` copies (about: the database's size with its WAL, and the files)."""
    total = 0
    for root, _, names in os.walk(data_dir):
        for n in names:
            try:
                total += os.lstat(os.path.join(root, n)).st_size
            except FileNotFoundError:
                pass
    return total


def _backup(data_dir: Path, dest: Path, clock: Callable[[], datetime]) -> dict:
    db_path = data_dir / DB_NAME
    taken = clock().astimezone(UTC)
    src = sqlite3.connect(f"file:{db_path}?mode=rw", uri=True, timeout=30, isolation_level=None)
    try:
        backup_database(src, dest, DB_NAME)  # the snapshot, before the files
    finally:
        src.close()
    copy = sqlite3.connect(dest / DB_NAME, isolation_level=None)
    try:
        copy.execute("PRAGMA journal_mode=DELETE")  # one file, nothing beside it
        version, rows = schema_version(copy), table_rows(copy)
    finally:
        copy.close()
    files = {}
    for rel in _files(data_dir):
        target = dest / FILES / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            _copy(data_dir / rel, target)
        except FileNotFoundError:  # removed since it was listed (the janitor, a replaced preview)
            continue
        files[rel.as_posix()] = {"bytes": target.stat().st_size, "sha256": sha256(target)}
    manifest = {
        "time": taken.isoformat(),
        "data_dir": str(data_dir.resolve()),
        "schema_version": version,
        "database": {"bytes": (dest / DB_NAME).stat().st_size, "sha256": sha256(dest / DB_NAME)},
        "rows": rows,
        "files": files,
        "file_count": len(files),
    }
    tmp = dest / f".{MANIFEST}.partial"
    tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n")
    tmp.replace(dest / MANIFEST)
    record_backup(data_dir, dest, manifest)  # for the status page (server/core/status.py)
    return manifest


def _files(data_dir: Path) -> list[Path]:
    """The data directory's files to back up, relative to it (folders that vanish while walked are skipped)."""
    out = []
    for root, dirs, names in os.walk(data_dir):
        here = Path(root).relative_to(data_dir)
        dirs[:] = sorted(d for d in dirs if not _skipped(here / d))
        out += [here / n for n in sorted(names) if not _skipped(here / n) and not os.path.islink(Path(root) / n)]
    return out


def _copy(src: Path, dst: Path) -> None:
    """`src`'s bytes and times at `dst`, private (0600) whatever `src`'s mode (an earlier release made 0644)."""
    shutil.copyfile(src, dst)
    st = os.stat(src)
    os.utime(dst, ns=(st.st_atime_ns, st.st_mtime_ns))
    os.chmod(dst, 0o600)


def table_rows(db: sqlite3.Connection) -> dict[str, int]:
    names = [r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
    return {n: db.execute(f'SELECT COUNT(*) FROM "{n}"').fetchone()[0] for n in names}


def read_manifest(src: Path) -> dict:
    """The backup's manifest, its database's and files' checksums checked (BackupError naming what differs)."""
    src = Path(src)
    try:
        manifest = json.loads((src / MANIFEST).read_text())
    except FileNotFoundError:
        raise BackupError(
            f"{src} has no {MANIFEST}: not a backup, or one that did not finish (the manifest is written last)"
        ) from None
    except (ValueError, OSError) as e:
        raise BackupError(f"{src / MANIFEST} cannot be read ({e}): a damaged backup. Nothing was restored") from None
    wrong = []
    for rel, want in [(DB_NAME, manifest["database"])] + [(f"{FILES}/{k}", v) for k, v in manifest["files"].items()]:
        path = src / rel
        if not path.is_file():
            wrong.append(f"{rel} is missing")
        elif sha256(path) != want["sha256"]:
            wrong.append(f"{rel} differs from its checksum")
    if wrong:
        more = f" (and {len(wrong) - 5} more)" if len(wrong) > 5 else ""
        raise BackupError(f"the backup {src} is damaged: {'; '.join(wrong[:5])}{more}. Nothing was restored")
    return manifest


def restore(src: Path, data_dir: Path, force: bool = False) -> dict:
    """Bring the backup `src` back into `data_dir` (new or empty; with `force` its contents are replaced);
    the manifest. Refused while a server holds the data directory's lock."""
    src, data_dir = Path(src), Path(data_dir)
    manifest = read_manifest(src)
    if data_dir.exists() and not data_dir.is_dir():
        raise BackupError(f"{data_dir} is a file: give a folder to restore into")
    data_dir.mkdir(parents=True, exist_ok=True)
    lock = lock_data_dir(data_dir)  # StartupError while a server uses it
    try:
        there = [p for p in data_dir.iterdir() if p.name != "server.lock"]
        if there and not force:
            raise BackupError(
                f"{data_dir} is not empty ({len(there)} entries, {', '.join(sorted(p.name for p in there)[:5])}): "
                "restore into a new folder, or give --force to replace what is there"
            )
        for p in there:
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
        for rel in manifest["files"]:
            target = data_dir / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            _copy(src / FILES / rel, target)
        tmp = data_dir / f".{DB_NAME}.restoring"
        _copy(src / DB_NAME, tmp)
        tmp.replace(data_dir / DB_NAME)  # last: a data directory with a database is a whole one
        db = sqlite3.connect(data_dir / DB_NAME, isolation_level=None)
        try:
            problems = [r[0] for r in db.execute("PRAGMA integrity_check")]
        finally:
            db.close()
        if problems != ["ok"]:
            raise BackupError(f"the restored database fails PRAGMA integrity_check: {'; '.join(problems[:5])}")
    finally:
        lock.close()
    return manifest
