"""Migrations at scale and their upkeep (issue #39, item 3): migration 2 reads its rows once (no subquery per
row: 8 000 roster rows took 53 s); `python -m server migrate --dry-run` says what it would do and an estimate,
changing nothing; the copies made before upgrades are pruned (the last 3 kept); a killed copy's hidden .partial
file is removed at the next start; a copy or a backup onto a full disk says so in one line and leaves nothing
behind, so that the same command can be run again."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from datetime import timedelta

import pytest

from server.core import migration_0002_courses
from server.core.migrations import KEEP_COPIES, LATEST, MigrationError, migrate
from tests.support.api import Clock
from tests.support.disk import filled, tmpfs
from tests.support.migrations import T0, query, unpack
from tests.support.scene import ROOT


def server(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "server", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)  # fmt: skip


class Recording:
    """A connection that keeps SQLite's plan of each statement moving rows (EXPLAIN QUERY PLAN, asked just before
    it runs), then runs it."""

    def __init__(self, db: sqlite3.Connection):
        self.db, self.plans = db, {}

    def execute(self, sql: str, *args):
        if sql.startswith("INSERT") and "SELECT" in sql and "course_students" in sql:
            self.plans[sql] = [r[3] for r in self.db.execute("EXPLAIN QUERY PLAN " + sql, *args)]
        return self.db.execute(sql, *args)


def test_migration_2_reads_its_rows_once_and_keeps_the_latest_name(tmp_path):
    """No correlated subquery in any of its statements (SQLite's plan says so), and each student's member row is
    their latest roster row's name with their first row's time, as before."""
    data = unpack(tmp_path)
    first, later = 1000.0, 2000.0
    db = sqlite3.connect(data / "jobs.sqlite3", isolation_level=None)
    try:
        aid = db.execute("SELECT id FROM course_assignments LIMIT 1").fetchone()[0]
        other = "b" + aid[1:]
        db.execute("INSERT INTO course_assignments (id, version, created_at) VALUES (?, 1, 0)", (other,))
        db.execute(
            "INSERT INTO course_students (assignment_id, student, name, email, token_hash, created_at) VALUES"
            " (?, 'zz', 'Old Name', 'old@x', 'h1', ?), (?, 'zz', 'New Name', 'new@x', 'h2', ?)",
            (aid, first, other, later),
        )
        rec = Recording(db)
        db.execute("BEGIN IMMEDIATE")
        migration_0002_courses.apply(rec)
        db.execute("ROLLBACK")
    finally:
        db.close()
    assert len(rec.plans) == 3, list(rec.plans)
    correlated = {sql[:60]: plan for sql, plan in rec.plans.items() if any("CORRELATED" in p for p in plan)}
    assert correlated == {}, correlated
    migrate(data, Clock(T0))
    member = query(data / "jobs.sqlite3", "SELECT name, email, created_at FROM course_members WHERE student = 'zz'")
    assert member == [("New Name", "new@x", first)]
    tokens = query(data / "jobs.sqlite3", "SELECT COUNT(*) FROM course_tokens WHERE person = 'zz'")
    assert tokens == [(2,)]


def test_migrate_dry_run_says_what_it_would_do_and_changes_nothing(tmp_path):
    data = unpack(tmp_path)
    rosters = query(data / "jobs.sqlite3", "SELECT COUNT(*) FROM course_students")[0][0]
    before = (data / "jobs.sqlite3").read_bytes()
    out = server("migrate", "--dry-run", "--data-dir", str(data))
    assert out.returncode == 0, out.stderr
    plan = json.loads(out.stdout)
    assert (plan["version"], plan["latest"]) == (0, LATEST), plan
    assert [m["number"] for m in plan["migrations"]] == list(range(1, LATEST + 1))
    assert plan["migrations"][1]["rows"] == rosters and plan["backup"]["bytes"] > 0, plan
    assert isinstance(plan["estimate_s"], float)
    assert plan["estimate_s"] >= 0
    assert "copy the database" in plan["steps"][0] and "migration 2 (courses" in plan["steps"][2], plan["steps"]
    assert "about" in out.stderr and "nothing was changed" in out.stderr, out.stderr
    assert (data / "jobs.sqlite3").read_bytes() == before
    assert not (data / "backups").exists()
    assert query(data / "jobs.sqlite3", "PRAGMA user_version") == [(0,)]


def test_copies_before_upgrades_are_pruned_and_partials_removed(tmp_path):
    data = unpack(tmp_path)
    backups = data / "backups"
    backups.mkdir()
    old = [backups / f"jobs-v0-2026120{d}T000000.000000Z.sqlite3" for d in range(1, 5)]
    for path in old:
        path.write_bytes(b"an earlier copy")
    partial = backups / ".jobs-v0-20261205T000000.000000Z.sqlite3.partial"
    partial.write_bytes(b"half a copy")
    restoring = data / ".jobs.sqlite3.restoring"
    restoring.write_bytes(b"half a restore")
    report = migrate(data, Clock(T0))
    kept = sorted(p.name for p in backups.iterdir())
    assert kept == sorted([report.backup.name, old[2].name, old[3].name]) and len(kept) == KEEP_COPIES, kept
    assert not partial.exists()
    assert not restoring.exists()
    partial.write_bytes(b"a copy killed at the next upgrade")
    assert migrate(data, Clock(T0 + timedelta(days=1))).applied == []  # a start with nothing to migrate
    assert not partial.exists()


def test_a_copy_before_the_upgrade_onto_a_full_disk_leaves_nothing(tmp_path):
    with tmpfs(tmp_path / "disk", "16m") as disk:
        data = unpack(disk)
        with filled(disk):
            with pytest.raises(MigrationError, match="no room for the copy") as e:
                migrate(data, Clock(T0))
            assert "\n" not in str(e.value)
            assert "Nothing was changed or left behind" in str(e.value)
            assert list((data / "backups").iterdir()) == []
            assert query(data / "jobs.sqlite3", "PRAGMA user_version") == [(0,)]
        assert migrate(data, Clock(T0)).after == LATEST  # space again: the same start works


def test_a_backup_onto_a_full_disk_says_so_in_one_line_and_leaves_nothing(tmp_path):
    data = unpack(tmp_path)
    with tmpfs(tmp_path / "disk", "4m") as disk:
        dest = disk / "backup"
        with filled(disk):
            out = server("backup", str(dest), "--data-dir", str(data))
            assert out.returncode == 1, out.stderr
            lines = out.stderr.strip().splitlines()
            assert len(lines) == 1 and "is full" in lines[0] and "run the same command again" in lines[0], lines
            assert not dest.exists(), list(dest.rglob("*"))
            assert sorted(p.name for p in disk.iterdir()) == ["fill"]
        out = server("backup", str(dest), "--data-dir", str(data))
        assert out.returncode == 0, out.stderr
        assert (dest / "manifest.json").is_file()


def test_a_killed_backups_partial_file_does_not_block_the_same_command(tmp_path):
    data = unpack(tmp_path)
    dest = tmp_path / "backup"
    dest.mkdir()
    (dest / ".jobs.sqlite3.partial").write_bytes(b"half a snapshot")
    out = server("backup", str(dest), "--data-dir", str(data))
    assert out.returncode == 0, out.stderr
    assert not (dest / ".jobs.sqlite3.partial").exists()
    assert (dest / "manifest.json").is_file()
