"""The course's tables, in the job store's database (DATA/jobs.sqlite3) beside the jobs and the grading runs.

- `course_assignments`: one per published assignment: its current version.
- `course_versions`: every version ever published (an edit adds one, the earlier ones are kept): the spec
  (its reference scene inline), the policy, and its open grading run (server/grading/: the run that grades
  every submission made under this version, sharing one reference mean and its noise baselines).
- `course_students`: the roster (and those who joined an open assignment by name): the SHA-256 of each
  one's token (the token itself is shown once and never kept), their extension if any.
- `course_submissions`: one per submission, written when its body is accepted (the API's clock): who, when,
  late or not, its file, the grading run it went to and whether it was handed to it yet (`handed`). Its
  grade is that run's row for it (grading_items, keyed by the submission's id), read, never copied.

Every write is one statement or one transaction (server/core/db.py); each thread has its own connection.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

from server.core.db import Tables
from server.grading.store import GradingStore

SCHEMA = """
CREATE TABLE IF NOT EXISTS course_assignments (
    id TEXT PRIMARY KEY,                  -- 32 hex digits (an open assignment's link carries it)
    version INTEGER NOT NULL,             -- the current version (1, 2, ...)
    created_at REAL NOT NULL              -- Unix time (s), the API's clock
);
CREATE TABLE IF NOT EXISTS course_versions (
    assignment_id TEXT NOT NULL,
    version INTEGER NOT NULL,
    spec TEXT NOT NULL,                   -- the grading spec (JSON, reference scene inline)
    policy TEXT NOT NULL,                 -- deadline, late cut-off and penalty, limits, feedback... (JSON)
    run_id TEXT NOT NULL,                 -- its open grading run (grading_runs.id)
    created_at REAL NOT NULL,
    PRIMARY KEY (assignment_id, version)
);
CREATE TABLE IF NOT EXISTS course_students (
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,                -- the roster's id
    name TEXT NOT NULL,
    email TEXT NOT NULL DEFAULT '',
    token_hash TEXT NOT NULL UNIQUE,      -- SHA-256 (hex) of their token: also the owner of their jobs
    self_declared INTEGER NOT NULL DEFAULT 0, -- joined an open assignment by a name they typed
    deadline REAL,                        -- their extension (Unix time); NULL: the assignment's
    created_at REAL NOT NULL,
    PRIMARY KEY (assignment_id, student)
);
CREATE TABLE IF NOT EXISTS course_submissions (
    id TEXT PRIMARY KEY,                  -- 32 hex digits
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,
    version INTEGER NOT NULL,             -- the version it is graded against
    run_id TEXT NOT NULL,                 -- that version's grading run; its row there is keyed by this id
    kind TEXT NOT NULL,                   -- scene, png or exr
    file TEXT NOT NULL,                   -- relative to DATA/course/
    accepted_at REAL NOT NULL,            -- Unix time (s): the API's clock when its body was accepted
    late INTEGER NOT NULL,                -- after the student's deadline when it came (its view reads the deadline now)
    handed INTEGER NOT NULL DEFAULT 0     -- its row is in the grading run (a restart hands those that are not)
);
CREATE INDEX IF NOT EXISTS course_submissions_student ON course_submissions (assignment_id, student, accepted_at);
"""

# a submission that holds an attempt: not (yet) found invalid or ungradable by its grading
HOLDS_ATTEMPT = "NOT (g.stage IS 'graded' AND g.status IN ('invalid', 'failed'))"


class CourseStore(Tables):
    def __init__(self, data_dir: Path):
        GradingStore(data_dir)  # the grading tables this store's queries join (created if new)
        super().__init__(data_dir, SCHEMA)

    # -- assignments and their versions --------------------------------------------------------

    def create(self, aid: str, spec: str, policy: dict, run_id: str, now: float) -> None:
        with self._tx() as db:
            db.execute("INSERT INTO course_assignments (id, version, created_at) VALUES (?, 1, ?)", (aid, now))
            db.execute(
                "INSERT INTO course_versions (assignment_id, version, spec, policy, run_id, created_at)"
                " VALUES (?, 1, ?, ?, ?, ?)",
                (aid, spec, json.dumps(policy), run_id, now),
            )

    def add_version(self, aid: str, spec: str, policy: dict, run_id: str, now: float) -> int:
        with self._tx() as db:
            version = db.execute("SELECT version FROM course_assignments WHERE id = ?", (aid,)).fetchone()[0] + 1
            db.execute(
                "INSERT INTO course_versions (assignment_id, version, spec, policy, run_id, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (aid, version, spec, json.dumps(policy), run_id, now),
            )
            db.execute("UPDATE course_assignments SET version = ? WHERE id = ?", (version, aid))
        return version

    def assignment(self, aid: str) -> dict | None:
        """The assignment with its current version's spec, policy and run (None if there is none)."""
        row = self.db.execute(
            "SELECT a.id, a.version, a.created_at, v.spec, v.policy, v.run_id, v.created_at AS version_at"
            " FROM course_assignments a JOIN course_versions v ON v.assignment_id = a.id AND v.version = a.version"
            " WHERE a.id = ?",
            (aid,),
        ).fetchone()
        return _version(row) if row else None

    def versions(self, aid: str) -> list[dict]:
        rows = self.db.execute(
            "SELECT assignment_id AS id, version, spec, policy, run_id, created_at AS version_at"
            " FROM course_versions WHERE assignment_id = ? ORDER BY version",
            (aid,),
        )
        return [_version(r) for r in rows]

    def assignments(self) -> list[str]:
        return [r[0] for r in self.db.execute("SELECT id FROM course_assignments ORDER BY created_at")]

    # -- students ------------------------------------------------------------------------------

    def students(self, aid: str) -> list[dict]:
        rows = self.db.execute("SELECT * FROM course_students WHERE assignment_id = ? ORDER BY student", (aid,))
        return [dict(r) for r in rows]

    def student(self, aid: str, student: str) -> dict | None:
        row = self.db.execute(
            "SELECT * FROM course_students WHERE assignment_id = ? AND student = ?", (aid, student)
        ).fetchone()
        return dict(row) if row else None

    def by_token(self, aid: str, token_hash: str) -> dict | None:
        row = self.db.execute(
            "SELECT * FROM course_students WHERE assignment_id = ? AND token_hash = ?", (aid, token_hash)
        ).fetchone()
        return dict(row) if row else None

    def on_a_roster(self, token_hash: str) -> bool:
        """Is this token's hash a student's of any assignment (a known identity: server/core/clients.py)?"""
        row = self.db.execute("SELECT 1 FROM course_students WHERE token_hash = ? LIMIT 1", (token_hash,)).fetchone()
        return row is not None

    def roster_kind(self, token_hash: str) -> str | None:
        """How this token's hash is on some assignment's roster: "roster" (put there by an instructor, on any),
        "joined" (only ever self-declared, by an open assignment's join), or None (on none)."""
        row = self.db.execute(
            "SELECT MIN(self_declared) FROM course_students WHERE token_hash = ?", (token_hash,)
        ).fetchone()
        return None if row is None or row[0] is None else "joined" if row[0] else "roster"

    def add_joined(self, aid: str, row: dict, now: float, most: int) -> bool:
        """A self-declared student (an open assignment's join), unless the assignment already has `most` of them:
        counted and added in one transaction, so that joins at once cannot pass the cap."""
        with self._tx() as db:
            have = db.execute(
                "SELECT COUNT(*) FROM course_students WHERE assignment_id = ? AND self_declared = 1", (aid,)
            ).fetchone()[0]
            if have >= most:
                return False
            db.execute(
                "INSERT INTO course_students (assignment_id, student, name, email, token_hash, self_declared,"
                " created_at) VALUES (?, ?, ?, ?, ?, 1, ?)",
                (aid, row["student"], row["name"], row["email"], row["token_hash"], now),
            )
        return True

    def add_students(self, aid: str, rows: list[dict], now: float) -> list[str]:
        """The roster's new students (dicts: student, name, email, token_hash, self_declared), in one
        transaction; those already on it keep their token (their name and email are updated). The ids added."""
        added = []
        with self._tx() as db:
            for r in rows:
                cur = db.execute(
                    "UPDATE course_students SET name = ?, email = ? WHERE assignment_id = ? AND student = ?",
                    (r["name"], r["email"], aid, r["student"]),
                )
                if cur.rowcount:
                    continue
                db.execute(
                    "INSERT INTO course_students (assignment_id, student, name, email, token_hash, self_declared,"
                    " created_at) VALUES (?, ?, ?, ?, ?, ?, ?)",
                    (aid, r["student"], r["name"], r["email"], r["token_hash"], int(r.get("self_declared", 0)), now),
                )
                added.append(r["student"])
        return added

    def set_token(self, aid: str, student: str, token_hash: str) -> bool:
        cur = self.db.execute(
            "UPDATE course_students SET token_hash = ? WHERE assignment_id = ? AND student = ?",
            (token_hash, aid, student),
        )
        return cur.rowcount == 1

    def extend(self, aid: str, student: str, deadline: float | None) -> bool:
        cur = self.db.execute(
            "UPDATE course_students SET deadline = ? WHERE assignment_id = ? AND student = ?", (deadline, aid, student)
        )
        return cur.rowcount == 1

    # -- submissions ---------------------------------------------------------------------------

    def add_submission(self, sub: dict, max_attempts: int | None, per_hour: int, hour_ago: float) -> str | None:
        """The submission's row, unless the student is past a cap: then which one ("attempts" or "hour"),
        with nothing written. Counting and writing are one transaction, so a burst cannot pass a cap."""
        with self._tx() as db:
            who = (sub["assignment_id"], sub["student"])
            recent = db.execute(
                "SELECT COUNT(*) FROM course_submissions WHERE assignment_id = ? AND student = ? AND accepted_at > ?",
                (*who, hour_ago),
            ).fetchone()[0]
            if recent >= per_hour:
                return "hour"
            if max_attempts is not None and self._attempts(db, *who) >= max_attempts:
                return "attempts"
            db.execute(
                "INSERT INTO course_submissions (id, assignment_id, student, version, run_id, kind, file,"
                " accepted_at, late) VALUES (:id, :assignment_id, :student, :version, :run_id, :kind, :file,"
                " :accepted_at, :late)",
                sub,
            )
        return None

    def attempts(self, aid: str, student: str) -> int:
        return self._attempts(self.db, aid, student)

    @staticmethod
    def _attempts(db: sqlite3.Connection, aid: str, student: str) -> int:
        return db.execute(
            "SELECT COUNT(*) FROM course_submissions s LEFT JOIN grading_items g ON g.run_id = s.run_id"
            f" AND g.student = s.id WHERE s.assignment_id = ? AND s.student = ? AND {HOLDS_ATTEMPT}",
            (aid, student),
        ).fetchone()[0]

    def remove_submission(self, sid: str) -> None:
        self.db.execute("DELETE FROM course_submissions WHERE id = ?", (sid,))

    def handed(self, sid: str, run_id: str) -> None:
        """Its row is in `run_id` (unless a regrade moved it to another run meanwhile: then it is handed again)."""
        self.db.execute("UPDATE course_submissions SET handed = 1 WHERE id = ? AND run_id = ?", (sid, run_id))

    def unhanded(self) -> list[dict]:
        """Submissions accepted but not yet in their grading run (a server stopped in between)."""
        rows = self.db.execute("SELECT * FROM course_submissions WHERE handed = 0 ORDER BY accepted_at")
        return [dict(r) for r in rows]

    def regrade(self, aid: str, version: int, run_id: str) -> list[dict]:
        """Every submission of the assignment moved to a new version's run, to be handed to it again."""
        with self._tx() as db:
            db.execute(
                "UPDATE course_submissions SET version = ?, run_id = ?, handed = 0 WHERE assignment_id = ?",
                (version, run_id, aid),
            )
        return [s for s in self.unhanded() if s["assignment_id"] == aid]

    def submissions(self, aid: str, student: str | None = None) -> list[dict]:
        """Submissions (one student's, or all) in the order they came, each with its grading row's stage,
        status and exact score (None until graded)."""
        sql = (
            "SELECT s.*, g.stage, g.status, g.score, g.max_score FROM course_submissions s LEFT JOIN grading_items g"
            " ON g.run_id = s.run_id AND g.student = s.id WHERE s.assignment_id = ?"
        )
        args: tuple = (aid,)
        if student is not None:
            sql, args = sql + " AND s.student = ?", (aid, student)
        return [dict(r) for r in self.db.execute(sql + " ORDER BY s.accepted_at, s.rowid", args)]

    def submission(self, aid: str, sid: str) -> dict | None:
        row = self.db.execute(
            "SELECT s.*, g.stage, g.status, g.score, g.max_score FROM course_submissions s LEFT JOIN grading_items g"
            " ON g.run_id = s.run_id AND g.student = s.id WHERE s.assignment_id = ? AND s.id = ?",
            (aid, sid),
        ).fetchone()
        return dict(row) if row else None


def _version(row: sqlite3.Row) -> dict:
    out = dict(row)
    out["spec"], out["policy"] = json.loads(out["spec"]), json.loads(out["policy"])
    return out
