"""Upgrades (server/core/migrations.py): the data directory of the release of 2026-12-05 (tests/fixtures/
release-2026-12-05/, made by tests/fixtures/make_release_fixture.py from that release's code) started by this
code's `python -m server` on loopback loses nothing: every job with its image, the grading run, each assignment's
brief, roster with extensions, submissions and grades, the students' tokens; the database was copied first and
now has the latest schema version, and its schema is a new database's. A database newer than this release is
refused, a failing migration leaves the last good version and names the copy, and two processes starting at
once migrate once."""

from __future__ import annotations

import hashlib
import json
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from server.core.migrations import LATEST, MIGRATIONS, Migration, MigrationError, migrate
from tests.support.api import Clock, Server, bearer, free_port
from tests.support.migrations import FIXTURE, T0, query, unpack
from tests.support.scene import ROOT

EXPECTED = json.loads((FIXTURE / "expected.json").read_text())
TEACHER = bearer(EXPECTED["instructor"])
VOLATILE = {"time_left", "late_time_left", "closed", "join"}  # as the fixture's script leaves them out
MOVED: set[str] = {"course_students"}  # tables a migration empties or drops on purpose: migration 2 moved the
# rosters of before courses into course_members, course_tokens and course_enrolments


def rows(db_path: Path) -> dict[str, int]:
    names = [r[0] for r in query(db_path, "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
    return {n: query(db_path, f'SELECT COUNT(*) FROM "{n}"')[0][0] for n in names}


def schema(db_path: Path) -> dict:
    """Each table's columns by name (ALTER TABLE appends a column: order differs, meaning not) and each index."""
    db = sqlite3.connect(db_path)
    try:
        tables = [r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        columns = {t: sorted(tuple(r[1:]) for r in db.execute(f'PRAGMA table_info("{t}")')) for t in tables}
        indexes = sorted(r for r in db.execute("SELECT name, tbl_name, sql FROM sqlite_master WHERE type = 'index'"))
        return {"columns": columns, "indexes": indexes}
    finally:
        db.close()


@pytest.fixture(scope="module")
def upgraded(tmp_path_factory):
    """The release's data directory as this code's server left it, with the fixture's row counts before it."""
    data = unpack(tmp_path_factory.mktemp("release"))
    before = rows(data / "jobs.sqlite3")
    assert query(data / "jobs.sqlite3", "PRAGMA user_version") == [(0,)]  # the release marked nothing
    with Server(data, workers=0, env={"TRACER_INSTRUCTOR_TOKEN": EXPECTED["instructor"]}) as server:
        yield server, data, before


def test_migrations_todays_release_starts_with_every_job_and_grade(upgraded):
    server, data, before = upgraded
    c = server.client
    assert query(data / "jobs.sqlite3", "PRAGMA user_version") == [(LATEST,)]
    copies = sorted((data / "backups").glob("jobs-v0-*.sqlite3"))
    assert len(copies) == 1, f"expected one copy made before the upgrade in {data / 'backups'}: {copies}"
    assert rows(copies[0]) == before  # the copy holds every row of the release's database
    after = rows(data / "jobs.sqlite3")
    fewer = {t: n for t, n in before.items() if t not in MOVED and after.get(t, 0) < n}
    assert fewer == {}, f"rows lost (tables with fewer rows than the release's): {before} -> {after}"

    for name, want in EXPECTED["jobs"].items():
        r = c.get(f"/api/jobs/{want['id']}", headers=bearer(want["token"]))
        assert r.status_code == 200, f"job {name}: {r.text}"
        assert (r.json()["status"], r.json()["error"]) == (want["status"], want["error"]), name
        image = c.get(f"/api/jobs/{want['id']}/image", headers=bearer(want["token"]))
        if want["image_sha256"] is None:
            assert image.status_code != 200, name
        else:
            assert image.status_code == 200, f"job {name}'s image: {image.text}"
            assert hashlib.sha256(image.content).hexdigest() == want["image_sha256"], f"job {name}'s image differs"

    run = c.get(f"/api/grade/{EXPECTED['grading_run']['id']}", headers=TEACHER).json()
    got = sorted([r["student"], r["status"], r["score"]] for r in run["reports"])
    assert (run["status"], got) == (EXPECTED["grading_run"]["status"], EXPECTED["grading_run"]["reports"])

    for name, want in EXPECTED["assignments"].items():
        aid = want["id"]
        brief = c.get(f"/api/assignments/{aid}", headers=TEACHER).json()
        # every field the release answered, with its value (a later release adds fields: the staff's `you`, the
        # late tokens'), and nothing of it missing
        assert {k: brief.get(k, "(missing)") for k in want["brief"]} == want["brief"], f"{name}'s brief"
        assert not VOLATILE & set(want["brief"])
        assert c.get(f"/api/assignments/{aid}/roster", headers=TEACHER).json()["students"] == want["roster"]
        subs = c.get(f"/api/assignments/{aid}/submissions", headers=TEACHER).json()["submissions"]
        keys = ("id", "student", "status", "score", "max_score", "late")
        got = [{k: s[k] for k in keys} for s in subs]
        for s in got:  # the release left it queued; this server may have taken it up since it started (its
            if s["id"] == EXPECTED["ungraded"] and s["status"] == "grading":  # render waits: it has no worker)
                s["status"] = "queued"
        assert got == want["submissions"], f"{name}'s submissions"
        assert c.get(f"/api/assignments/{aid}/grades.csv", headers=TEACHER).text == want["grades_csv"]
        for student, token in want["tokens"].items():  # each student's link still works, and is theirs
            r = c.get(f"/api/assignments/{aid}", headers=bearer(token))
            assert r.status_code == 200 and r.json()["student"]["id"] == student, r.text
            mine = c.get(f"/api/assignments/{aid}/submissions", headers=bearer(token)).json()["submissions"]
            assert {s["id"] for s in mine} == {s["id"] for s in want["submissions"] if s["student"] == student}
    assert any(s["id"] == EXPECTED["ungraded"] for s in EXPECTED["assignments"]["rostered"]["submissions"])


def test_migrations_a_migrated_schema_is_a_new_databases(upgraded, tmp_path):
    """A column or index added to a store's schema and forgotten in a migration (or the reverse) shows here."""
    from server.course.lms_store import LmsStore
    from server.course.store import CourseStore
    from server.jobs.store import JobStore
    from server.lti.store import LtiStore

    _, data, _ = upgraded
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    report = migrate(fresh, Clock(T0))
    assert (report.new, report.after, report.backup) == (True, LATEST, None)  # new: marked, nothing copied
    JobStore(fresh), CourseStore(fresh), LmsStore(fresh), LtiStore(fresh)  # every store the app opens
    assert query(fresh / "jobs.sqlite3", "PRAGMA user_version") == [(LATEST,)]
    old, new = schema(data / "jobs.sqlite3"), schema(fresh / "jobs.sqlite3")
    differ = {
        t: {"migrated": sorted(set(old["columns"].get(t, [])) - set(new["columns"].get(t, []))),
            "new": sorted(set(new["columns"].get(t, [])) - set(old["columns"].get(t, [])))}
        for t in set(old["columns"]) | set(new["columns"]) if old["columns"].get(t) != new["columns"].get(t)
    }  # fmt: skip
    assert differ == {}, f"columns (name, type, notnull, default, pk) of a migrated database and a new one: {differ}"
    assert old["indexes"] == new["indexes"]


def test_migrations_a_database_newer_than_this_release_is_refused(tmp_path):
    data = unpack(tmp_path)
    db = sqlite3.connect(data / "jobs.sqlite3")
    db.execute(f"PRAGMA user_version = {LATEST + 1}")
    db.close()
    before = (data / "jobs.sqlite3").read_bytes()
    with pytest.raises(MigrationError, match=f"schema version {LATEST + 1}, newer than this release's {LATEST}"):
        migrate(data, Clock(T0))
    argv = [sys.executable, "-m", "server", "--data-dir", str(data), "--port", str(free_port()), "--workers", "0"]
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 1, out.stderr
    assert "cannot start" in out.stderr
    assert "a later release wrote it" in out.stderr
    assert "Traceback" not in out.stderr
    assert (data / "jobs.sqlite3").read_bytes() == before
    assert not (data / "backups").exists()


def test_migrations_a_failing_migration_leaves_the_last_good_version(tmp_path):
    data = unpack(tmp_path)

    def add_column(db):
        db.execute("ALTER TABLE jobs ADD COLUMN course_id TEXT")

    def half_then_fail(db):
        db.execute("CREATE TABLE half_made (x INTEGER)")
        raise ValueError("a row the migration cannot read")

    steps = (*MIGRATIONS, Migration(LATEST + 1, "a column", add_column), Migration(LATEST + 2, "fails", half_then_fail))
    with pytest.raises(MigrationError) as e:
        migrate(data, Clock(T0), migrations=steps)
    copy = data / "backups" / "jobs-v0-20261206T093000.000000Z.sqlite3"
    message = str(e.value)
    assert f"migration {LATEST + 2} (fails)" in message
    assert "a row the migration cannot read" in message
    assert f"stays at schema version {LATEST + 1}" in message
    assert str(copy) in message
    db = data / "jobs.sqlite3"
    assert query(db, "PRAGMA user_version") == [(LATEST + 1,)]
    assert "course_id" in {r[1] for r in query(db, "PRAGMA table_info(jobs)")}  # the good one stays
    assert query(db, "SELECT name FROM sqlite_master WHERE name = 'half_made'") == []  # the failed one is undone
    assert query(copy, "PRAGMA user_version") == [(0,)] and rows(copy)["jobs"] == rows(db)["jobs"]


MIGRATE = """
import json, sys
from pathlib import Path
from server.core.migrations import migrate
print("ready", flush=True)
r = migrate(Path(sys.argv[1]))
print(json.dumps({"applied": r.applied, "backup": str(r.backup) if r.backup else None}), flush=True)
"""


def test_migrations_two_processes_starting_at_once_migrate_once(tmp_path):
    """Both wait on the lock (the test holds it until both are started), then one migrates, and the other
    finds the work done: one copy, one migration applied."""
    import fcntl

    data = unpack(tmp_path)
    lock = open(data / "migrate.lock", "a")  # noqa: SIM115 (closed below)
    fcntl.flock(lock, fcntl.LOCK_EX)
    procs = [
        subprocess.Popen([sys.executable, "-c", MIGRATE, str(data)], cwd=ROOT, stdout=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    try:
        assert [p.stdout.readline().strip() for p in procs] == ["ready", "ready"]
    finally:
        fcntl.flock(lock, fcntl.LOCK_UN)
        lock.close()
    reports = [json.loads(p.communicate(timeout=60)[0]) for p in procs]
    assert [p.returncode for p in procs] == [0, 0]
    assert sorted(len(r["applied"]) for r in reports) == [0, len(MIGRATIONS)], reports
    assert len(list((data / "backups").glob("jobs-v0-*.sqlite3"))) == 1
    assert query(data / "jobs.sqlite3", "PRAGMA user_version") == [(LATEST,)]


def test_migrations_by_hand_before_a_start(tmp_path):
    """`python -m server migrate`: the report on stdout; refused while a server holds the data directory."""
    from server.core.startup import lock_data_dir

    data = unpack(tmp_path)
    argv = [sys.executable, "-m", "server", "migrate", "--data-dir", str(data)]
    held = lock_data_dir(data)
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120)
    held.close()
    assert out.returncode == 1 and "another server is using the data directory" in out.stderr, out.stderr
    assert query(data / "jobs.sqlite3", "PRAGMA user_version") == [(0,)]
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert (report["before"], report["after"], len(report["applied"])) == (0, LATEST, len(MIGRATIONS))
    assert Path(report["backup"]).is_file() and Path(report["backup"]).parent == data / "backups"
    shutil.rmtree(data)
