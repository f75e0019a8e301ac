"""Schema versions of the data directory's database (DATA/jobs.sqlite3), and the migrations between them.

The version is SQLite's `PRAGMA user_version` of the database (0 in a database no release marked: the release
of 2026-12-05 and earlier). `MIGRATIONS` is the ordered list of `Migration(number, name, apply)`; `LATEST` is the
last one's number, the version this code reads and writes. `migrate(data_dir, clock)` brings a database to
LATEST; the server runs it at start-up, after it took the data directory's lock and before any store opens the
database (server/main.py's lifespan, and `python -m server` before it serves), and a deployer may run it by
hand with `python -m server migrate` (server/__main__.py). Under an exclusive lock (`fcntl.flock` of
DATA/migrate.lock: two processes starting at once migrate once, the second finds the work done), it:

- leaves a new database (no file, or one without a table) to the stores, which make the current schema, and
  marks it LATEST;
- refuses a database newer than LATEST (a later release wrote it; this one cannot read it): run that release,
  or restore the backup made before the upgrade;
- for an older one, first makes a backup through SQLite's online backup API, DATA/backups/jobs-v{old}-{UTC
  time}.sqlite3, then applies each later migration in its own transaction (BEGIN IMMEDIATE ... COMMIT, with
  `user_version` set in the same transaction), logging each. A migration that fails is rolled back: the
  database stays at the last good version, and the error names the backup. The copies of earlier upgrades
  are pruned: the last KEEP_COPIES stay. A copy the disk has no room for is a MigrationError with nothing
  left behind (and nothing migrated): free space and start again;
- first of all, removes the hidden `.*.partial` files a killed copy left in DATA/backups/ (and a killed
  restore's `.jobs.sqlite3.restoring`).

Every migration is linear in the rows it moves (set-based statements, never a subquery per row; an index
where a statement looks rows up): bench/migrate.py measures an upgrade of 300 000 roster rows and 1 000 000
jobs (BENCHMARKS.md), and `plan` (`python -m server migrate --dry-run`) says what `migrate` would do and
about how long it would take, from the rows each migration moves (`Migration.rows`) and the database's size.

Adding a migration (a new table, a new column, rows moved from one table to another):
1. write `def _m0002_name(db: sqlite3.Connection) -> None` below, plain SQL on `db` (inside its transaction
   already: no BEGIN/COMMIT, and no `executescript`, which commits), importing nothing else of server/;
2. append `Migration(2, "what it does", _m0002_name)` to MIGRATIONS (numbers go up by one; never renumber or
   edit a released one: a database that ran it will not run it again);
3. change the store's own schema too (its `CREATE TABLE IF NOT EXISTS`, which makes a new database): a new
   column goes BOTH there (new databases) and in the migration (old ones). tests/server/core/test_migrations.py
   catches a forgotten one: a migrated old database's schema (each table's columns, compared by name since
   ALTER TABLE appends, and each index) must equal a fresh one's;
4. a release that changes the schema checks in its own fixture (tests/fixtures/make_release_fixture.py) so
   that the next one proves it loses nothing of it.

The `jobs` table's columns added before versions existed are still added by JobStore when missing
(server/jobs/store.py, `_add_columns`); the baseline below marks the schema of 2026-12-05 and changes nothing.

Going back: a migrated database cannot be read by the release before it (it refuses a newer version). Stop the
server, put the backup named in the log in place of DATA/jobs.sqlite3 (and remove jobs.sqlite3-wal and -shm),
and start the older release (docs/service.md, "Backups and upgrades").
"""

from __future__ import annotations

import fcntl
import logging
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from server.core import migration_0002_courses
from server.core.files import is_disk_full
from server.core.startup import DB_NAME, StartupError

log = logging.getLogger("server.migrations")

LOCK_NAME = "migrate.lock"  # DATA/migrate.lock: held while a process migrates
BACKUPS = "backups"  # DATA/backups/: the copies made before each upgrade
LOCK_WAIT = 600.0  # seconds a process waits for another one's migration before it gives up
LOCK_POLL = 0.05  # seconds between two tries of the lock
KEEP_COPIES = 3  # copies made before upgrades kept in DATA/backups/ (the newest)
# the dry run's estimate, from bench/migrate.py on the development machine (BENCHMARKS.md), a little under what
# it measured: a slower disk takes longer
COPY_BYTES_PER_S = 50e6  # the copy before the upgrade (76 MB/s measured)
ROWS_PER_S = 15e3  # roster rows migration 2 moves (17 000/s measured, 300 000 rows)


@dataclass(frozen=True)
class Migration:
    number: int  # the schema version it brings the database to
    name: str  # what it does, for the log
    apply: Callable[[sqlite3.Connection], None]  # plain SQL, inside the migration's transaction
    rows: Callable[[sqlite3.Connection], int] | None = None  # the rows it moves (the dry run's estimate)


def _add_columns(db: sqlite3.Connection, added: dict[str, tuple[str, ...]]) -> None:
    """Each table's new columns (`name TYPE ...`) that it lacks, in the tables that exist (a database whose server
    never opened a table gets it whole from its store)."""
    for table, columns in added.items():
        have = {r[1] for r in db.execute(f'PRAGMA table_info("{table}")')}
        if not have:
            continue
        for column in columns:
            if column.split()[0] not in have:
                db.execute(f"ALTER TABLE {table} ADD COLUMN {column}")


def _m0001_baseline(db: sqlite3.Connection) -> None:
    """The schema of the release of 2026-12-05 (jobs, grading runs, assignments with per-assignment rosters), as
    its stores make it: nothing to change, the version is marked."""


def _m0003_lti_platforms_and_logins(db: sqlite3.Connection) -> None:
    """LTI (issue #39): a platform's `trust_emails` and `service_origins`, a login's client `address`; in the
    tables that exist (a database whose server never opened LTI's gets them whole from its store)."""
    added = {
        "lti_platforms": (
            "trust_emails INTEGER NOT NULL DEFAULT 0",
            "service_origins TEXT NOT NULL DEFAULT ''",
        ),
        "lti_logins": ("address TEXT NOT NULL DEFAULT ''",),
    }
    _add_columns(db, added)


def _m0004_lms_refusals_and_leavers(db: sqlite3.Connection) -> None:
    """The LMS (issue #41, item 8): a score's HTTP `status` when the LMS refused it for good (its row then
    `failed`) and its `comment`, and a member's `left_at` (the roster sync found them gone from the LMS course:
    inactive, kept); in the tables that exist (a database whose server never opened them gets them whole from
    their stores)."""
    added = {"course_lti_scores": ("status INTEGER", "comment TEXT"), "course_members": ("left_at REAL",)}
    _add_columns(db, added)


def _m0005_late_tokens(db: sqlite3.Connection) -> None:
    """Late tokens and extensions' history (issue #41, item 4): a course's `late_tokens`, a submission's
    `tokens_spent`, the tokens granted and the extensions granted, each kept with who, when, before, after and why."""
    added = {
        "courses": ("late_tokens INTEGER NOT NULL DEFAULT 0",),
        "course_submissions": ("tokens_spent INTEGER NOT NULL DEFAULT 0",),
    }
    _add_columns(db, added)
    if not {r[1] for r in db.execute('PRAGMA table_info("courses")')}:
        return  # no course tables yet: the course store makes them whole
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_token_grants (course_id TEXT NOT NULL, student TEXT NOT NULL,"
        " added INTEGER NOT NULL, before INTEGER NOT NULL, after INTEGER NOT NULL, who TEXT NOT NULL,"
        " why TEXT NOT NULL DEFAULT '', at REAL NOT NULL)"
    )
    db.execute("CREATE INDEX IF NOT EXISTS course_token_grants_student ON course_token_grants (course_id, student)")
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_extensions (assignment_id TEXT NOT NULL, student TEXT NOT NULL,"
        " before REAL, after REAL, who TEXT NOT NULL, why TEXT NOT NULL DEFAULT '', at REAL NOT NULL)"
    )
    db.execute("CREATE INDEX IF NOT EXISTS course_extensions_student ON course_extensions (assignment_id, student)")


def _m0006_manual_grades(db: sqlite3.Connection) -> None:
    """Staff-graded items (issue #41, item 2): the manual grades, each assignment's release and anonymity, the
    graders each student's submission is assigned to (server/course/schema.py has the same tables)."""
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_manual_grades (submission_id TEXT NOT NULL, item TEXT NOT NULL,"
        " assignment_id TEXT NOT NULL, rubric TEXT NOT NULL, points REAL, comment TEXT NOT NULL DEFAULT '',"
        " grader TEXT, graded_at REAL NOT NULL, PRIMARY KEY (submission_id, item))"
    )
    db.execute("CREATE INDEX IF NOT EXISTS course_manual_grades_assignment ON course_manual_grades (assignment_id)")
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_manual (assignment_id TEXT PRIMARY KEY, released_at REAL,"
        " released_by TEXT, anonymous INTEGER NOT NULL DEFAULT 0)"
    )
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_graders (assignment_id TEXT NOT NULL, student TEXT NOT NULL,"
        " grader TEXT NOT NULL, PRIMARY KEY (assignment_id, student))"
    )


def _m0007_course_audit(db: sqlite3.Connection) -> None:
    """The course's audit trail (issue #41, item 5): the `course_audit` table and its indexes, as
    server/course/schema.py makes them (a new table: no rows move)."""
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_audit (id INTEGER PRIMARY KEY AUTOINCREMENT, course_id TEXT NOT NULL,"
        " at REAL NOT NULL, who TEXT NOT NULL, action TEXT NOT NULL, assignment_id TEXT, student TEXT,"
        " target TEXT NOT NULL, before TEXT, after TEXT, why TEXT NOT NULL DEFAULT '')"
    )
    db.execute("CREATE INDEX IF NOT EXISTS course_audit_course ON course_audit (course_id, id)")
    db.execute("CREATE INDEX IF NOT EXISTS course_audit_student ON course_audit (course_id, student, id)")
    db.execute("CREATE INDEX IF NOT EXISTS course_audit_assignment ON course_audit (assignment_id, id)")


def _m0008_regrade_requests(db: sqlite3.Connection) -> None:
    """Regrade requests (issue #41, item 3): the requests, their events, the tests' points they set, as
    server/course/schema.py makes them (new tables: no rows move)."""
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_regrade_requests (id TEXT PRIMARY KEY, assignment_id TEXT NOT NULL,"
        " submission_id TEXT NOT NULL, student TEXT NOT NULL, item TEXT NOT NULL, kind TEXT NOT NULL,"
        " reason TEXT NOT NULL, status TEXT NOT NULL, reply TEXT NOT NULL DEFAULT '', points REAL,"
        " created_at REAL NOT NULL, answered_at REAL, answered_by TEXT)"
    )
    db.execute(
        "CREATE INDEX IF NOT EXISTS course_regrade_requests_assignment ON course_regrade_requests (assignment_id,"
        " status)"
    )
    db.execute(
        "CREATE INDEX IF NOT EXISTS course_regrade_requests_submission ON course_regrade_requests (submission_id, item)"
    )
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_regrade_events (id INTEGER PRIMARY KEY AUTOINCREMENT,"
        " request_id TEXT NOT NULL, at REAL NOT NULL, who TEXT NOT NULL, kind TEXT NOT NULL, change TEXT NOT NULL)"
    )
    db.execute("CREATE INDEX IF NOT EXISTS course_regrade_events_request ON course_regrade_events (request_id, id)")
    db.execute(
        "CREATE TABLE IF NOT EXISTS course_test_overrides (submission_id TEXT NOT NULL, test TEXT NOT NULL,"
        " assignment_id TEXT NOT NULL, version INTEGER NOT NULL, original REAL NOT NULL, points REAL NOT NULL,"
        " request_id TEXT NOT NULL, at REAL NOT NULL, PRIMARY KEY (submission_id, test))"
    )
    db.execute("CREATE INDEX IF NOT EXISTS course_test_overrides_assignment ON course_test_overrides (assignment_id)")


MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "baseline: the release of 2026-12-05", _m0001_baseline),
    Migration(
        2,
        "courses: assignments and rosters into the default course",
        migration_0002_courses.apply,
        migration_0002_courses.rows,
    ),
    Migration(
        3, "lti: a platform's trust_emails and service_origins, a login's address", _m0003_lti_platforms_and_logins
    ),
    Migration(4, "lms: a score's refusal status and comment, a member's left_at", _m0004_lms_refusals_and_leavers),
    Migration(
        5, "course: late tokens (a course's, a submission's spent, grants) and extensions' history", _m0005_late_tokens
    ),
    Migration(6, "manual grades: staff-graded items, their release, graders", _m0006_manual_grades),
    Migration(7, "course: the audit trail (course_audit)", _m0007_course_audit),
    Migration(8, "course: regrade requests, their events, the tests' points they set", _m0008_regrade_requests),
)
LATEST = MIGRATIONS[-1].number


class MigrationError(StartupError):
    """The database cannot be brought to this release's schema: the message says why and what to do."""


@dataclass
class Report:
    """What `migrate` did."""

    before: int  # the version found
    after: int  # the version left
    new: bool = False  # a new database, marked LATEST
    backup: Path | None = None  # the copy made before the first migration
    applied: list[str] = field(default_factory=list)  # "N name" of each migration applied


def utc_now() -> datetime:
    return datetime.now(UTC)


def schema_version(db: sqlite3.Connection) -> int:
    return db.execute("PRAGMA user_version").fetchone()[0]


def migrate(
    data_dir: Path,
    clock: Callable[[], datetime] = utc_now,
    migrations: tuple[Migration, ...] = MIGRATIONS,
    lock_wait: float = LOCK_WAIT,
) -> Report:
    """Bring DATA/jobs.sqlite3 to the last of `migrations` (see the module's docstring); MigrationError if it
    cannot. `clock` names the backup; `lock_wait` bounds the wait for another process's migration (seconds)."""
    data_dir = Path(data_dir)
    latest = migrations[-1].number
    with _exclusive(data_dir / LOCK_NAME, lock_wait):
        remove_partials(data_dir)
        db = sqlite3.connect(data_dir / DB_NAME, timeout=30, isolation_level=None)
        try:
            db.execute("PRAGMA journal_mode=WAL")  # as the stores open it
            version = schema_version(db)
            tables = db.execute("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table'").fetchone()[0]
            if tables == 0:  # new: the stores make the current schema
                db.execute(f"PRAGMA user_version = {latest}")
                return Report(version, latest, new=True)
            if version > latest:
                raise MigrationError(
                    f"the database {data_dir / DB_NAME} has schema version {version}, newer than this release's "
                    f"{latest}: a later release wrote it, and this one cannot read it. Run that release again, or "
                    f"restore the copy made before the upgrade (in {data_dir / BACKUPS}: jobs-v{latest}-*.sqlite3, "
                    "see docs/service.md, Backups and upgrades). Nothing was changed"
                )
            report = Report(version, version)
            if version == latest:
                return report
            try:
                report.backup = backup_database(db, data_dir / BACKUPS, copy_name(version, clock()))
            except (OSError, sqlite3.Error) as e:
                if not is_disk_full(e):
                    raise
                size = (data_dir / DB_NAME).stat().st_size
                raise MigrationError(
                    f"no room for the copy of {data_dir / DB_NAME} made before the upgrade (about {size} bytes, in "
                    f"{data_dir / BACKUPS}): the disk is full. Nothing was changed or left behind: free space, then "
                    "start again"
                ) from None
            log.info("schema version %d, this release's %d: database copied to %s", version, latest, report.backup)
            for m in migrations:
                if m.number <= version:
                    continue
                _apply(db, m, report, data_dir)
            prune_copies(data_dir / BACKUPS)
            return report
        finally:
            db.close()


def copy_name(version: int, t: datetime) -> str:
    """The name of the copy made before upgrading a database at schema `version`, at time `t`."""
    return f"jobs-v{version}-{_stamp(t)}.sqlite3"


def plan(
    data_dir: Path, clock: Callable[[], datetime] = utc_now, migrations: tuple[Migration, ...] = MIGRATIONS
) -> dict:
    """What `migrate` would do to DATA/jobs.sqlite3, and about how long it would take; nothing is changed (the
    database is opened read-only). `steps` says it in words."""
    data_dir = Path(data_dir)
    path, latest = data_dir / DB_NAME, migrations[-1].number
    out: dict = {"database": str(path), "latest": latest, "migrations": [], "backup": None, "estimate_s": 0.0}
    if not path.is_file():
        out.update(version=None, steps=[f"no database: a new one is made at schema version {latest}"])
        return out
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=30, isolation_level=None)
    try:
        version = schema_version(db)
        tables = db.execute("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table'").fetchone()[0]
        out["version"] = version
        if tables == 0:
            out["steps"] = [f"an empty database: marked schema version {latest}"]
            return out
        if version > latest:
            out["steps"] = [f"schema version {version} is newer than this release's {latest}: refused, nothing done"]
            return out
        if version == latest:
            out["steps"] = [f"schema version {version}, this release's: nothing to do"]
            return out
        size = sum(p.stat().st_size for p in data_dir.glob(f"{DB_NAME}*") if p.name in (DB_NAME, f"{DB_NAME}-wal"))
        copy = data_dir / BACKUPS / copy_name(version, clock())
        out["backup"] = {"path": str(copy), "bytes": size, "estimate_s": round(size / COPY_BYTES_PER_S, 1)}
        steps = [f"copy the database ({size} bytes) to {copy} (about {size / COPY_BYTES_PER_S:.1f} s)"]
        total = size / COPY_BYTES_PER_S
        for m in migrations:
            if m.number <= version:
                continue
            n = m.rows(db) if m.rows is not None else 0
            took = n / ROWS_PER_S
            total += took
            out["migrations"].append({"number": m.number, "name": m.name, "rows": n, "estimate_s": round(took, 1)})
            steps.append(f"migration {m.number} ({m.name}): {n} rows (about {took:.1f} s)")
        old = sorted((data_dir / BACKUPS).glob("jobs-v*-*.sqlite3"))
        if len(old) + 1 > KEEP_COPIES:
            steps.append(f"remove the oldest {len(old) + 1 - KEEP_COPIES} of the copies of earlier upgrades")
        out["estimate_s"] = round(total, 1)
        out["steps"] = steps
        return out
    finally:
        db.close()


def remove_partials(data_dir: Path) -> list[Path]:
    """The hidden leftovers of a copy or a restore that was killed: DATA/backups/.*.partial and
    DATA/.jobs.sqlite3.restoring; the paths removed."""
    gone = [*Path(data_dir, BACKUPS).glob(".*.partial"), *Path(data_dir).glob(f".{DB_NAME}.restoring")]
    for path in gone:
        path.unlink(missing_ok=True)
        log.info("removed %s, left by a copy that did not finish", path)
    return gone


def prune_copies(folder: Path, keep: int = KEEP_COPIES) -> list[Path]:
    """The copies made before upgrades beyond the newest `keep` removed (their names sort by time within a
    version, and versions only go up); the paths removed."""
    copies = sorted(folder.glob("jobs-v*-*.sqlite3"), key=lambda p: (_version_of(p), p.name))
    gone = copies[: max(0, len(copies) - keep)]
    for path in gone:
        path.unlink(missing_ok=True)
        log.info("removed %s: the last %d copies made before upgrades are kept", path, keep)
    return gone


def _version_of(path: Path) -> int:
    try:
        return int(path.name.split("-")[1][1:])
    except (IndexError, ValueError):
        return -1


def _apply(db: sqlite3.Connection, m: Migration, report: Report, data_dir: Path) -> None:
    started = time.monotonic()
    db.execute("BEGIN IMMEDIATE")
    try:
        m.apply(db)
        db.execute(f"PRAGMA user_version = {int(m.number)}")
        db.execute("COMMIT")
    except Exception as e:
        if db.in_transaction:
            db.execute("ROLLBACK")
        raise MigrationError(
            f"migration {m.number} ({m.name}) of {data_dir / DB_NAME} failed: {type(e).__name__}: {e}. The database "
            f"stays at schema version {report.after}; the copy made before the upgrade is {report.backup}. Start "
            "the release before this one, or put that copy back once the cause is fixed"
        ) from e
    report.after = m.number
    report.applied.append(f"{m.number} {m.name}")
    log.info("migration %d (%s) applied in %.2f s", m.number, m.name, time.monotonic() - started)


def backup_database(src: sqlite3.Connection, folder: Path, name: str) -> Path:
    """A consistent copy of the database of `src` (SQLite's online backup API: one read transaction, writers in
    WAL mode go on) at folder/name, written whole under a temporary name first."""
    folder.mkdir(parents=True, exist_ok=True)
    path, tmp = folder / name, folder / f".{name}.partial"
    tmp.unlink(missing_ok=True)
    try:
        dest = sqlite3.connect(tmp)
        try:
            src.backup(dest)
        finally:
            dest.close()
        tmp.replace(path)
    except BaseException:  # a full disk, a kill: nothing half-made is left
        tmp.unlink(missing_ok=True)
        raise
    return path


def _stamp(t: datetime) -> str:
    return t.astimezone(UTC).strftime("%Y%m%dT%H%M%S.%fZ")


class _exclusive:
    """`with`: an exclusive flock of `path`, tried every LOCK_POLL s for at most `wait` s (MigrationError past it)."""

    def __init__(self, path: Path, wait: float):
        self.path, self.wait = path, wait

    def __enter__(self) -> None:
        self.file = open(self.path, "a")  # noqa: SIM115 (closed on leaving)
        for _ in range(max(1, int(self.wait / LOCK_POLL))):
            try:
                fcntl.flock(self.file, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return
            except BlockingIOError:
                time.sleep(LOCK_POLL)
        self.file.close()
        raise MigrationError(
            f"another process has been migrating {self.path.parent / DB_NAME} for {self.wait:.0f} s (it holds "
            f"{self.path}): wait for it to end, or stop it"
        )

    def __exit__(self, *exc) -> None:
        fcntl.flock(self.file, fcntl.LOCK_UN)
        self.file.close()
