"""Migration 2 (server/core/migrations.py), courses (issue #31): the data of a server from before courses moves
into the `default` course, nothing lost. Plain SQL on one connection, inside the migration's transaction; it
imports nothing of the course package (a migration is frozen: the tables as they were then, whatever the code
says later).

Before: assignments were global, each with its own roster (`course_students`: one token per student per
assignment). After: each assignment is in a course (`course_assignments.course_id`, `default` for these),
the course's roster holds each student once (`course_members`, the latest row's name and email), every token
that worked still works (`course_tokens`: one row per old token, so each old link still opens its
assignment, and its jobs keep their owner), and each assignment's roster is its enrolments
(`course_enrolments`, with the extensions).

Every statement is set-based and reads `course_students` once (a sort at most: n log n): 300 000 roster rows
migrate in seconds (bench/migrate.py, BENCHMARKS.md). `rows(db)` counts what it moves, for
`python -m server migrate --dry-run`'s estimate."""

from __future__ import annotations

import sqlite3

TABLES = """
CREATE TABLE IF NOT EXISTS courses (
    id TEXT PRIMARY KEY, name TEXT NOT NULL, created_at REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS course_staff (
    course_id TEXT NOT NULL, person TEXT NOT NULL, name TEXT NOT NULL, email TEXT NOT NULL DEFAULT '',
    role TEXT NOT NULL, lti_user TEXT, gen INTEGER NOT NULL DEFAULT 0, created_at REAL NOT NULL,
    PRIMARY KEY (course_id, person)
);
CREATE TABLE IF NOT EXISTS course_members (
    course_id TEXT NOT NULL, student TEXT NOT NULL, name TEXT NOT NULL, email TEXT NOT NULL DEFAULT '',
    self_declared INTEGER NOT NULL DEFAULT 0, every INTEGER NOT NULL DEFAULT 0, lti_user TEXT,
    gen INTEGER NOT NULL DEFAULT 0, created_at REAL NOT NULL, PRIMARY KEY (course_id, student)
);
CREATE TABLE IF NOT EXISTS course_tokens (
    token_hash TEXT PRIMARY KEY, course_id TEXT NOT NULL, kind TEXT NOT NULL, person TEXT NOT NULL,
    created_at REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS course_enrolments (
    assignment_id TEXT NOT NULL, student TEXT NOT NULL, deadline REAL, created_at REAL NOT NULL,
    PRIMARY KEY (assignment_id, student)
);
CREATE INDEX IF NOT EXISTS course_members_lti ON course_members (course_id, lti_user);
CREATE INDEX IF NOT EXISTS course_tokens_person ON course_tokens (course_id, kind, person)
"""


def rows(db: sqlite3.Connection) -> int:
    """The roster rows this migration moves (0 when there is nothing to move)."""
    if not db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'course_students'").fetchone():
        return 0
    return db.execute("SELECT COUNT(*) FROM course_students").fetchone()[0]


def apply(db: sqlite3.Connection) -> None:
    """Move a database from before courses into the `default` course (inside the migration's transaction). A
    database whose server never made an assignment has no course tables yet: its stores make them."""
    cols = [r[1] for r in db.execute("PRAGMA table_info(course_assignments)")]
    if not cols or "course_id" in cols:
        return
    now = db.execute("SELECT (julianday('now') - 2440587.5) * 86400.0").fetchone()[0]
    db.execute("ALTER TABLE course_assignments ADD COLUMN course_id TEXT NOT NULL DEFAULT 'default'")
    for statement in TABLES.split(";"):
        if statement.strip():
            db.execute(statement.strip())
    db.execute("INSERT OR IGNORE INTO courses (id, name, created_at) VALUES ('default', 'Default course', ?)", (now,))
    if not db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'course_students'").fetchone():
        return
    # each student once: the name and email of their latest roster row, their first row's time. One pass over
    # the rows sorted by student (window functions), never a subquery per row: a correlated subquery on
    # `student`, which no index leads with, made this quadratic (8 000 rows took 53 s; issue #39, item 3)
    db.execute(
        "INSERT OR IGNORE INTO course_members (course_id, student, name, email, self_declared, every, gen, created_at)"
        " SELECT 'default', student, name, email, self_declared, 0, 0, first FROM ("
        " SELECT student, name, email, self_declared, MIN(created_at) OVER (PARTITION BY student) AS first,"
        " ROW_NUMBER() OVER (PARTITION BY student ORDER BY created_at DESC, rowid DESC) AS latest"
        " FROM course_students) WHERE latest = 1"
    )
    db.execute(
        "INSERT OR IGNORE INTO course_tokens (token_hash, course_id, kind, person, created_at)"
        " SELECT token_hash, 'default', 'student', student, created_at FROM course_students"
    )
    db.execute(
        "INSERT OR IGNORE INTO course_enrolments (assignment_id, student, deadline, created_at)"
        " SELECT assignment_id, student, deadline, created_at FROM course_students"
    )
    db.execute("DROP TABLE course_students")
