"""The course's tables, in the job store's database (DATA/jobs.sqlite3) beside the jobs and the grading runs.

- `courses`: one per course (a department's server holds several); `default` holds what came from before
  courses (server/core/migrations: assignments and their rosters moved into it, nothing lost).
- `course_staff`: a course's instructors and TAs (`role`), each with a generation (`gen`) of their token.
- `course_members`: the course's roster, enrolled once: one identity per student per course, across its
  assignments and their workspace jobs (`lti_user`: the LMS's user, when they came from one; `every`: enrolled
  in every assignment of the course, the ones published later too).
- `course_tokens`: the SHA-256 of each token that names a member or a staff member of a course (the token
  itself is never kept: it is derived from the data directory's secret, server/course/people.py).
- `course_assignments`: one per published assignment, in a course: its current version.
- `course_versions`: every version ever published (an edit adds one, the earlier ones are kept): the spec
  (its reference scene inline), the policy, and its open grading run (server/grading/: the run that grades
  every submission made under this version, sharing one reference mean and its noise baselines).
- `course_enrolments`: who is on an assignment's roster (members of its course), with their extension if any.
- `course_submissions`: one per submission, written when its body is accepted (the API's clock): who, when,
  late or not, its file, the grading run it went to and whether it was handed to it yet (`handed`). Its
  grade is that run's row for it (grading_items, keyed by the submission's id), read, never copied.
- `course_manual_grades`, `course_manual`, `course_graders`: staff-graded items (server/course/manual_store.py).

- `course_audit`: the audit trail (server/course/audit.py): each change's event, written in the change's own
  transaction by the method that makes it, when it is given a `By` (who, when, why).

The members and enrolments are read and written by the mixin server/course/roster_store.py, the submissions
by server/course/submission_store.py; courses, staff, tokens and assignments here.

Every write is one statement or one transaction (server/core/db.py); each thread has its own connection.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import cast

from server.core.db import Tables
from server.core.roles import Kind
from server.course.audit import By, Target, record
from server.course.manual_store import ManualTables
from server.course.roster_store import RosterTables
from server.course.schema import SCHEMA, AssignmentRow, CourseRow, StaffRow, TokenGrantRow, TokenRow, VersionRow
from server.course.submission_store import SubmissionTables
from server.grading.store import GradingStore

DEFAULT_COURSE = "default"  # the course of the assignments from before courses, and of those published without one


class CourseStore(ManualTables, RosterTables, SubmissionTables, Tables):
    def __init__(self, data_dir: Path, now: float = 0.0):
        GradingStore(data_dir)  # the grading tables this store's queries join (created if new)
        super().__init__(data_dir, SCHEMA)  # (a database from before courses: server/core/migrations.py, 2)
        self.db.execute(
            "INSERT OR IGNORE INTO courses (id, name, created_at) VALUES (?, 'Default course', ?)",
            (DEFAULT_COURSE, now),
        )

    # -- assignments and their versions --------------------------------------------------------

    def create(
        self,
        aid: str,
        spec: str,
        policy: dict,
        run_id: str,
        now: float,
        cid: str = DEFAULT_COURSE,
        by: By | None = None,
    ) -> None:
        """A new assignment of course `cid`, its roster the members enrolled in every assignment of the course."""
        with self._tx() as db:
            after = {"version": 1, "name": json.loads(spec).get("name"), "policy": policy}
            record(by, db, "publish", Target(cid, aid), None, after)
            db.execute(
                "INSERT INTO course_assignments (id, version, created_at, course_id) VALUES (?, 1, ?, ?)",
                (aid, now, cid),
            )
            db.execute(
                "INSERT OR IGNORE INTO course_enrolments (assignment_id, student, created_at)"
                " SELECT ?, student, ? FROM course_members WHERE course_id = ? AND every = 1",
                (aid, now, cid),
            )
            db.execute(
                "INSERT INTO course_versions (assignment_id, version, spec, policy, run_id, created_at)"
                " VALUES (?, 1, ?, ?, ?, ?)",
                (aid, spec, json.dumps(policy), run_id, now),
            )

    def add_version(self, aid: str, spec: str, policy: dict, run_id: str, now: float, by: By | None = None) -> int:
        """A new version of the assignment (an edit's; a regrade's, the same spec and policy). With `by`: an `edit`
        event, before and after the policy's fields that changed, and whether the spec did."""
        with self._tx() as db:
            row = db.execute(
                "SELECT a.version, a.course_id, v.spec, v.policy FROM course_assignments a JOIN course_versions v"
                " ON v.assignment_id = a.id AND v.version = a.version WHERE a.id = ?",
                (aid,),
            ).fetchone()
            version = row["version"] + 1
            if by is not None:
                old = json.loads(row["policy"])
                changed = sorted(k for k in {*old, *policy} if old.get(k) != policy.get(k))
                spec_changed = json.loads(row["spec"]) != json.loads(spec)
                before = {"version": row["version"], "policy": {k: old.get(k) for k in changed}}
                after = {"version": version, "policy": {k: policy.get(k) for k in changed}}
                after["spec_changed"] = spec_changed
                record(by, db, "edit", Target(row["course_id"], aid), before, after)
                self.record_rescore(db, by, Target(row["course_id"], aid), json.loads(row["spec"]), json.loads(spec))
            db.execute(
                "INSERT INTO course_versions (assignment_id, version, spec, policy, run_id, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (aid, version, spec, json.dumps(policy), run_id, now),
            )
            db.execute("UPDATE course_assignments SET version = ? WHERE id = ?", (version, aid))
        return version

    def assignment(self, aid: str) -> AssignmentRow | None:
        """The assignment with its current version's spec, policy and run (None if there is none)."""
        row = self.db.execute(
            "SELECT a.id, a.version, a.created_at, a.course_id, v.spec, v.policy, v.run_id, v.created_at AS version_at"
            " FROM course_assignments a JOIN course_versions v ON v.assignment_id = a.id AND v.version = a.version"
            " WHERE a.id = ?",
            (aid,),
        ).fetchone()
        return cast(AssignmentRow, _version(row)) if row else None

    def versions(self, aid: str) -> list[VersionRow]:
        rows = self.db.execute(
            "SELECT assignment_id AS id, version, spec, policy, run_id, created_at AS version_at"
            " FROM course_versions WHERE assignment_id = ? ORDER BY version",
            (aid,),
        )
        return [cast(VersionRow, _version(r)) for r in rows]

    def assignments(self, cid: str | None = None) -> list[str]:
        """The ids of every assignment (or those of course `cid`), oldest first."""
        if cid is None:
            return [r[0] for r in self.db.execute("SELECT id FROM course_assignments ORDER BY created_at")]
        rows = self.db.execute("SELECT id FROM course_assignments WHERE course_id = ? ORDER BY created_at", (cid,))
        return [r[0] for r in rows]

    # -- courses and their staff ---------------------------------------------------------------

    def add_course(self, cid: str, name: str, now: float) -> bool:
        """A new course (False: the id is taken)."""
        cur = self.db.execute("INSERT OR IGNORE INTO courses (id, name, created_at) VALUES (?, ?, ?)", (cid, name, now))
        return cur.rowcount == 1

    def course(self, cid: str) -> CourseRow | None:
        row = self.db.execute("SELECT * FROM courses WHERE id = ?", (cid,)).fetchone()
        return cast(CourseRow, dict(row)) if row else None

    def courses(self) -> list[CourseRow]:
        return [cast(CourseRow, dict(r)) for r in self.db.execute("SELECT * FROM courses ORDER BY created_at, id")]

    def rename_course(self, cid: str, name: str) -> None:
        self.db.execute("UPDATE courses SET name = ? WHERE id = ?", (name, cid))

    def set_late_tokens(self, cid: str, n: int, by: By | None = None) -> None:
        """The course's late tokens per student (with `by`: a `tokens.course` event, before and after)."""
        with self._tx() as db:
            was = db.execute("SELECT late_tokens FROM courses WHERE id = ?", (cid,)).fetchone()
            db.execute("UPDATE courses SET late_tokens = ? WHERE id = ?", (n, cid))
            if was is not None and was[0] != n:
                record(by, db, "tokens.course", Target(cid), {"late_tokens": was[0]}, {"late_tokens": n})

    def token_grants(self, cid: str, student: str) -> list[TokenGrantRow]:
        """A student's grants of late tokens in a course, oldest first (server/course/tokens.py)."""
        rows = self.db.execute(
            "SELECT * FROM course_token_grants WHERE course_id = ? AND student = ? ORDER BY at, rowid", (cid, student)
        )
        return [cast(TokenGrantRow, dict(r)) for r in rows]

    def add_staff(self, cid: str, row: dict, now: float, by: By | None = None) -> None:
        """A staff member (dict: person, name, email, role, lti_user), or their name, email and role updated (with
        `by`: a `staff.add` event, or `staff.change` when something changed)."""
        with self._tx() as db:
            was = db.execute(
                "SELECT name, email, role FROM course_staff WHERE course_id = ? AND person = ?", (cid, row["person"])
            ).fetchone()
            db.execute(
                "INSERT INTO course_staff (course_id, person, name, email, role, lti_user, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT (course_id, person) DO UPDATE SET name = excluded.name,"
                " email = excluded.email, role = excluded.role, lti_user = COALESCE(excluded.lti_user, lti_user)",
                (cid, row["person"], row["name"], row.get("email", ""), row["role"], row.get("lti_user"), now),
            )
            after = {"name": row["name"], "email": row.get("email", ""), "role": str(row["role"])}
            before = dict(was) if was is not None else None
            if before != after:
                action = "staff.add" if before is None else "staff.change"
                record(by, db, action, Target(cid, staff=row["person"]), before, after)

    def staff(self, cid: str) -> list[StaffRow]:
        rows = self.db.execute("SELECT * FROM course_staff WHERE course_id = ? ORDER BY person", (cid,))
        return [cast(StaffRow, dict(r)) for r in rows]

    def staff_member(self, cid: str, person: str) -> StaffRow | None:
        row = self.db.execute("SELECT * FROM course_staff WHERE course_id = ? AND person = ?", (cid, person)).fetchone()
        return cast(StaffRow, dict(row)) if row else None

    def remove_staff(self, cid: str, person: str, by: By | None = None) -> bool:
        with self._tx() as db:
            was = db.execute(
                "SELECT name, email, role FROM course_staff WHERE course_id = ? AND person = ?", (cid, person)
            ).fetchone()
            cur = db.execute("DELETE FROM course_staff WHERE course_id = ? AND person = ?", (cid, person))
            if was is not None:
                record(by, db, "staff.remove", Target(cid, staff=person), dict(was), None)
            db.execute("DELETE FROM course_tokens WHERE course_id = ? AND kind = 'staff' AND person = ?", (cid, person))
        return cur.rowcount == 1

    def by_lti(self, cid: str, kind: str, lti_user: str) -> dict | None:
        """The member (kind student) or staff member of a course that an LMS knows by `lti_user`."""
        table, key = ("course_members", "student") if kind == Kind.STUDENT else ("course_staff", "person")
        row = self.db.execute(
            f"SELECT *, {key} AS person FROM {table} WHERE course_id = ? AND lti_user = ?", (cid, lti_user)
        ).fetchone()
        return dict(row) if row else None

    # -- tokens --------------------------------------------------------------------------------

    def token(self, token_hash: str) -> TokenRow | None:
        """Whose token this is: {token_hash, course_id, kind, person, created_at}, or None."""
        row = self.db.execute("SELECT * FROM course_tokens WHERE token_hash = ?", (token_hash,)).fetchone()
        return cast(TokenRow, dict(row)) if row else None

    def keep_token(self, cid: str, kind: str, person: str, token_hash: str, now: float) -> None:
        self.db.execute(
            "INSERT OR IGNORE INTO course_tokens (token_hash, course_id, kind, person, created_at)"
            " VALUES (?, ?, ?, ?, ?)",
            (token_hash, cid, kind, person, now),
        )

    def token_hashes(self, cid: str, kind: str, person: str) -> list[str]:
        rows = self.db.execute(
            "SELECT token_hash FROM course_tokens WHERE course_id = ? AND kind = ? AND person = ?", (cid, kind, person)
        )
        return [r[0] for r in rows]

    def next_gen(self, cid: str, kind: str, person: str, by: By | None = None) -> int:
        """A new generation of someone's token: every token of theirs stops working. The new generation (with
        `by`: a `link.renew` event, the generations before and after; never the token)."""
        table, key = ("course_members", "student") if kind == Kind.STUDENT else ("course_staff", "person")
        with self._tx() as db:
            db.execute(f"UPDATE {table} SET gen = gen + 1 WHERE course_id = ? AND {key} = ?", (cid, person))
            db.execute("DELETE FROM course_tokens WHERE course_id = ? AND kind = ? AND person = ?", (cid, kind, person))
            gen = db.execute(f"SELECT gen FROM {table} WHERE course_id = ? AND {key} = ?", (cid, person)).fetchone()[0]
            target = Target(cid, student=person) if kind == Kind.STUDENT else Target(cid, staff=person)
            record(by, db, "link.renew", target, {"link": gen - 1}, {"link": gen})
            return gen

    def on_a_roster(self, token_hash: str) -> bool:
        """Is this token's hash a member's or a staff member's (a known identity: server/core/clients.py)?"""
        return self.token(token_hash) is not None


def _version(row: sqlite3.Row) -> dict:
    out = dict(row)
    out["spec"], out["policy"] = json.loads(out["spec"]), json.loads(out["policy"])
    return out
