"""Reading a data directory's database for the upgrade tests (tests/server/core/test_migrations.py and the bench's)."""

from __future__ import annotations

import sqlite3
import tarfile
from datetime import UTC, datetime
from pathlib import Path

from tests.support.scene import ROOT

FIXTURE = ROOT / "tests" / "fixtures" / "release-2026-12-05"


T0 = datetime(2026, 12, 6, 9, 30, tzinfo=UTC)  # the tests' clock, for the names of the copies


def unpack(where: Path) -> Path:
    """The release's data directory, unpacked into `where` (its DATA/ folder)."""
    with tarfile.open(FIXTURE / "data.tar.gz") as tar:
        tar.extractall(where, filter="data")
    return where / "data"


def query(db_path: Path, sql: str) -> list[tuple]:
    db = sqlite3.connect(db_path)
    try:
        return db.execute(sql).fetchall()
    finally:
        db.close()
