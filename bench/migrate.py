"""An upgrade of a big data directory: the release of 2026-12-05's database with `--students` roster rows and
`--jobs` jobs, brought to this release's schema (issue #39, item 3; BENCHMARKS.md, "Migrations").

    python -m bench.migrate [--students 300000] [--jobs 1000000] [--keep DIR] [--json FILE]

The database is the release's own (its schema, from tests/fixtures/release-2026-12-05/data.tar.gz, as that
release's stores made it), filled in SQL: `--jobs` finished jobs (a short scene each), and `--students` roster
rows (`course_students`) in assignments of 300 students, each student on the rosters of 10 assignments of their
course (so migration 2 merges 10 rows into each member). Then, timed:
1. `python -m server migrate --dry-run`'s plan (server/core/migrations.py, `plan`): its estimate;
2. `migrate`: the copy before the upgrade, then each migration (its own time, from its log line);
3. the stores opened on the migrated database, as a starting server opens them (their schemas, new indexes).
It checks that nothing was lost (every job; every roster row a token and an enrolment; each student one member)
and prints the times as JSON. Nothing here is a test: tests/bench/test_bench_migrate.py runs it small.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import sqlite3
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIXTURE = ROOT / "tests" / "fixtures" / "release-2026-12-05" / "data.tar.gz"
CLASS = 300  # students on one assignment's roster
ASSIGNMENTS = 10  # assignments of one course: each student is on the roster of each
SCENE = json.dumps({"version": 1, "name": "bench", "film": {"width": 64, "height": 48}, "objects": []})


def release_schema() -> list[str]:
    """The release's CREATE statements (tables, then indexes), read from the fixture's database."""
    with tempfile.TemporaryDirectory(prefix="bench-migrate-schema-") as tmp:
        with tarfile.open(FIXTURE) as tar:
            member = tar.getmember("data/jobs.sqlite3")
            tar.extractall(tmp, members=[member], filter="data")
        db = sqlite3.connect(Path(tmp) / "data" / "jobs.sqlite3")
        try:
            return [r[0] for r in db.execute("SELECT sql FROM sqlite_master WHERE sql IS NOT NULL ORDER BY type DESC")]
        finally:
            db.close()


def make(data: Path, students: int, jobs: int) -> dict:
    """A data directory of the release with `students` roster rows and `jobs` jobs; seconds it took, rows."""
    data.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    db = sqlite3.connect(data / "jobs.sqlite3", isolation_level=None)
    try:
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("BEGIN")
        for sql in release_schema():
            db.execute(sql)
        now = time.time() - 86400
        db.execute(
            "WITH RECURSIVE n(k) AS (SELECT 0 UNION ALL SELECT k + 1 FROM n WHERE k + 1 < ?)"
            " INSERT INTO jobs (id, status, created_at, started_at, finished_at, name, scene, width, height, spp,"
            " max_seconds, samples_total, samples_done, spp_done, owner)"
            " SELECT printf('job%019d', k), 'done', ?2 + k * 0.01, ?2 + k * 0.01, ?2 + k * 0.01 + 1, 'bench', ?3,"
            " 64, 48, 4, 600, 12288, 12288, 4, printf('%064x', k % 50000) FROM n",
            (jobs, now, SCENE),
        )
        assignments = max(1, -(-students // CLASS))
        db.execute(
            "WITH RECURSIVE n(k) AS (SELECT 0 UNION ALL SELECT k + 1 FROM n WHERE k + 1 < ?)"
            " INSERT INTO course_assignments (id, version, created_at) SELECT printf('%032x', k), 1, ?2 + k FROM n",
            (assignments, now),
        )
        # row k: course c = k / (CLASS * ASSIGNMENTS), its assignment a, its student c * CLASS + k % CLASS
        db.execute(
            "WITH RECURSIVE n(k) AS (SELECT 0 UNION ALL SELECT k + 1 FROM n WHERE k + 1 < ?1)"
            " INSERT INTO course_students (assignment_id, student, name, email, token_hash, self_declared, deadline,"
            " created_at)"
            " SELECT printf('%032x', k / ?2), printf('s%07d', (k / (?2 * ?3)) * ?2 + k % ?2),"
            " printf('Student %d', k), printf('s%d@example.edu', k), printf('%064x', k + 1000000000), 0,"
            " CASE WHEN k % 17 = 0 THEN ?4 + 7 * 86400 END, ?4 + k * 0.001 FROM n",
            (students, CLASS, ASSIGNMENTS, now),
        )
        db.execute("COMMIT")
        db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        members = db.execute("SELECT COUNT(DISTINCT student) FROM course_students").fetchone()[0]
    finally:
        db.close()
    return {"seconds": round(time.perf_counter() - started, 2), "members": members}


class Times(logging.Handler):
    """Each migration's own time, from its log line ("migration %d (%s) applied in %.2f s")."""

    def __init__(self):
        super().__init__()
        self.applied: dict[str, float] = {}

    def emit(self, record: logging.LogRecord) -> None:
        if record.msg.startswith("migration %d (%s) applied in"):
            number, name, seconds = record.args
            self.applied[f"{number} {name}"] = round(seconds, 2)


def run(data: Path, students: int, jobs: int) -> dict:
    from server.core.migrations import migrate, plan

    made = make(data, students, jobs)
    size = sum(p.stat().st_size for p in data.glob("jobs.sqlite3*"))
    started = time.perf_counter()
    dry = plan(data)
    dry_s = time.perf_counter() - started
    times = Times()
    logger = logging.getLogger("server.migrations")
    logger.addHandler(times)
    logger.setLevel(logging.INFO)
    try:
        started = time.perf_counter()
        report = migrate(data)
        migrate_s = time.perf_counter() - started
    finally:
        logger.removeHandler(times)
    started = time.perf_counter()
    from server.course.store import CourseStore
    from server.grading.store import GradingStore
    from server.jobs.store import JobStore

    stores = [JobStore(data), GradingStore(data), CourseStore(data)]
    for s in stores:
        s.close_connections()
    stores_s = time.perf_counter() - started
    db = sqlite3.connect(data / "jobs.sqlite3")
    try:
        count = {t: db.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]  # noqa: S608 (the names are ours)
                 for t in ("jobs", "course_members", "course_tokens", "course_enrolments")}  # fmt: skip
    finally:
        db.close()
    want = {"jobs": jobs, "course_members": made["members"], "course_tokens": students, "course_enrolments": students}
    if count != want:
        raise SystemExit(f"rows lost in the upgrade: {count}, expected {want}")
    copy_s = migrate_s - sum(times.applied.values())
    return {
        "students": students,
        "jobs": jobs,
        "members": made["members"],
        "database_bytes": size,
        "make_s": made["seconds"],
        "dry_run": {"seconds": round(dry_s, 2), "estimate_s": dry["estimate_s"], "steps": dry["steps"]},
        "migrate_s": round(migrate_s, 2),
        "copy_s": round(copy_s, 2),
        "applied_s": times.applied,
        "stores_open_s": round(stores_s, 2),
        "upgrade_s": round(migrate_s + stores_s, 2),
        "backup": str(report.backup),
        "rows": count,
    }


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="bench.migrate", description=__doc__.split("\n\n")[0])
    p.add_argument("--students", type=int, default=300_000, help="roster rows (course_students) of the old release")
    p.add_argument("--jobs", type=int, default=1_000_000)
    p.add_argument("--keep", type=Path, help="make the data directory here (a new folder) and keep it")
    p.add_argument("--json", type=Path, help="write the results as JSON here")
    args = p.parse_args(argv)
    load = os.getloadavg()
    print(f"{platform.machine()}, {os.cpu_count()} cores, load {load[0]:.1f}, SQLite {sqlite3.sqlite_version}",
          flush=True)  # fmt: skip
    if args.keep:
        result = run(args.keep, args.students, args.jobs)
    else:
        with tempfile.TemporaryDirectory(prefix="bench-migrate-") as tmp:
            result = run(Path(tmp) / "data", args.students, args.jobs)
    result["load_before"] = round(load[0], 1)
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
