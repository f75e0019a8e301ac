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

Every write is one statement or one transaction (server/core/db.py); each thread has its own connection.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable
from pathlib import Path
from typing import cast

from server.core.db import Tables
from server.core.roles import Kind
from server.course.audit import By, Target, record
from server.course.manual_store import ManualTables
from server.course.policy import iso
from server.course.schema import SCHEMA, CourseRow, StaffRow
from server.grading.store import GradingStore

DEFAULT_COURSE = "default"  # the course of the assignments from before courses, and of those published without one

# A roster student as the service reads one (an enrolment joined with its member): the columns of the
# per-assignment roster of before courses, so that every rule reads a student as it did.
STUDENT = (
    "SELECT e.assignment_id, e.student, m.name, m.email, m.self_declared, e.deadline, e.created_at, m.course_id,"
    " m.lti_user, m.left_at FROM course_enrolments e JOIN course_assignments a ON a.id = e.assignment_id"
    " JOIN course_members m ON m.course_id = a.course_id AND m.student = e.student"
)

# a submission that holds an attempt: not (yet) found invalid or ungradable by its grading
HOLDS_ATTEMPT = "NOT (g.stage IS 'graded' AND g.status IN ('invalid', 'failed'))"


class CourseStore(ManualTables, Tables):
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

    def assignment(self, aid: str) -> dict | None:
        """The assignment with its current version's spec, policy and run (None if there is none)."""
        row = self.db.execute(
            "SELECT a.id, a.version, a.created_at, a.course_id, v.spec, v.policy, v.run_id, v.created_at AS version_at"
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

    def token(self, token_hash: str) -> dict | None:
        """Whose token this is: {token_hash, course_id, kind, person}, or None."""
        row = self.db.execute("SELECT * FROM course_tokens WHERE token_hash = ?", (token_hash,)).fetchone()
        return dict(row) if row else None

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

    # -- the course's members ------------------------------------------------------------------

    def members(self, cid: str) -> list[dict]:
        rows = self.db.execute("SELECT * FROM course_members WHERE course_id = ? ORDER BY student", (cid,))
        return [dict(r) for r in rows]

    def member(self, cid: str, student: str) -> dict | None:
        row = self.db.execute(
            "SELECT * FROM course_members WHERE course_id = ? AND student = ?", (cid, student)
        ).fetchone()
        return dict(row) if row else None

    def roster_kind(self, token_hash: str) -> str | None:
        """How this token's hash is known to a course: "roster" (a member an instructor or an LMS put there, or
        staff), "joined" (a member who only joined an open assignment by a name), or None (unknown)."""
        row = self.db.execute(
            "SELECT t.kind, m.self_declared FROM course_tokens t LEFT JOIN course_members m ON t.kind = 'student'"
            " AND m.course_id = t.course_id AND m.student = t.person WHERE t.token_hash = ?",
            (token_hash,),
        ).fetchone()
        if row is None or (row["kind"] == Kind.STUDENT and row["self_declared"] is None):
            return None
        return "joined" if row["kind"] == Kind.STUDENT and row["self_declared"] else "roster"

    def add_joined(self, aid: str, cid: str, row: dict, now: float, most: int, by: By | None = None) -> bool:
        """A self-declared member on assignment `aid` (an open assignment's join), unless it already has `most` of
        them: counted and added in one transaction, so that joins at once cannot pass the cap."""
        with self._tx() as db:
            have = db.execute(
                "SELECT COUNT(*) FROM course_enrolments e JOIN course_members m ON m.course_id = ?"
                " AND m.student = e.student WHERE e.assignment_id = ? AND m.self_declared = 1",
                (cid, aid),
            ).fetchone()[0]
            if have >= most:
                return False
            db.execute(
                "INSERT INTO course_members (course_id, student, name, email, self_declared, created_at)"
                " VALUES (?, ?, ?, ?, 1, ?)",
                (cid, row["student"], row["name"], row["email"], now),
            )
            db.execute(
                "INSERT INTO course_enrolments (assignment_id, student, created_at) VALUES (?, ?, ?)",
                (aid, row["student"], now),
            )
            after = {"name": row["name"], "email": row["email"], "self_declared": True}
            record(by, db, "student.join", Target(cid, aid, student=row["student"]), None, after)
        return True

    def add_members(self, cid: str, rows: list[dict], now: float, enrol: list[str], by: By | None = None) -> list[str]:
        """Members (dicts: student, name, email, self_declared, every, lti_user) in one transaction: a new one
        added, one already there gets the name and email given (and `every` once set stays set); each enrolled in
        the assignments `enrol` names (and, with `every`, in every assignment of the course). The ids added.
        With `by`: a `student.add` event for each one added, `student.change` for one whose name, email or
        `every` changed, `student.enrol` for one already a member newly on an assignment `enrol` names."""
        added = []
        with self._tx() as db:
            for r in rows:
                was = db.execute(
                    "SELECT name, email, every FROM course_members WHERE course_id = ? AND student = ?",
                    (cid, r["student"]),
                ).fetchone()
                cur = db.execute(
                    "UPDATE course_members SET name = ?, email = ?, every = MAX(every, ?),"
                    " lti_user = COALESCE(?, lti_user) WHERE course_id = ? AND student = ?",
                    (r["name"], r["email"], int(r.get("every", 0)), r.get("lti_user"), cid, r["student"]),
                )
                if not cur.rowcount:
                    db.execute(
                        "INSERT INTO course_members (course_id, student, name, email, self_declared, every, lti_user,"
                        " created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        (cid, r["student"], r["name"], r["email"], int(r.get("self_declared", 0)),
                         int(r.get("every", 0)), r.get("lti_user"), now),
                    )  # fmt: skip
                    added.append(r["student"])
                if by is not None:
                    _member_event(db, by, cid, r, was, enrol)
                aids = list(enrol)
                if r.get("every"):
                    aids += [a[0] for a in db.execute("SELECT id FROM course_assignments WHERE course_id = ?", (cid,))]
                for aid in dict.fromkeys(aids):
                    enrolled = db.execute(
                        "INSERT OR IGNORE INTO course_enrolments (assignment_id, student, created_at) VALUES (?, ?, ?)",
                        (aid, r["student"], now),
                    ).rowcount
                    if enrolled and was is not None and aid in enrol:
                        target = Target(cid, aid, student=r["student"])
                        record(by, db, "student.enrol", target, None, {"enrolled": True})
        return added

    def set_left(self, cid: str, students: list[str], when: float | None, by: By | None = None) -> int:
        """Members who left the course's LMS course (`when`: inactive from then; kept with their submissions and
        grades) or came back (None: active again). How many changed (with `by`: a `student.left` or
        `student.back` event for each)."""
        changed = 0
        with self._tx() as db:
            for s in students:
                n = db.execute(
                    "UPDATE course_members SET left_at = ? WHERE course_id = ? AND student = ? AND"
                    + (" left_at IS NULL" if when is not None else " left_at IS NOT NULL"),
                    (when, cid, s),
                ).rowcount
                changed += n
                if n:
                    action, before, after = (
                        ("student.left", True, False) if when is not None else ("student.back", False, True)
                    )
                    record(by, db, action, Target(cid, student=s), {"active": before}, {"active": after})
        return changed

    def remove_member(self, cid: str, student: str, by: By | None = None) -> bool:
        """Off the course's rosters (their submissions are kept; their tokens stop working)."""
        with self._tx() as db:
            was = db.execute(
                "SELECT name, email, every FROM course_members WHERE course_id = ? AND student = ?", (cid, student)
            ).fetchone()
            cur = db.execute("DELETE FROM course_members WHERE course_id = ? AND student = ?", (cid, student))
            if was is not None:
                before = {"name": was["name"], "email": was["email"], "every": bool(was["every"])}
                record(by, db, "student.remove", Target(cid, student=student), before, None)
            db.execute(
                "DELETE FROM course_enrolments WHERE student = ? AND assignment_id IN"
                " (SELECT id FROM course_assignments WHERE course_id = ?)",
                (student, cid),
            )
            db.execute(
                "DELETE FROM course_tokens WHERE course_id = ? AND kind = 'student' AND person = ?", (cid, student)
            )
        return cur.rowcount == 1

    # -- an assignment's roster (its enrolments) -----------------------------------------------

    def students(self, aid: str) -> list[dict]:
        return [dict(r) for r in self.db.execute(STUDENT + " WHERE e.assignment_id = ? ORDER BY e.student", (aid,))]

    def student(self, aid: str, student: str) -> dict | None:
        row = self.db.execute(STUDENT + " WHERE e.assignment_id = ? AND e.student = ?", (aid, student)).fetchone()
        return dict(row) if row else None

    def by_token(self, aid: str, token_hash: str) -> dict | None:
        """The student of this assignment's roster whose token this is (a member of its course enrolled in it)."""
        row = self.db.execute(
            STUDENT + " JOIN course_tokens t ON t.course_id = m.course_id AND t.kind = 'student'"
            " AND t.person = m.student WHERE e.assignment_id = ? AND t.token_hash = ?",
            (aid, token_hash),
        ).fetchone()
        return dict(row) if row else None

    def enrol(self, aid: str, student: str, now: float, by: By | None = None) -> None:
        """A member of the assignment's course on its roster (if not already: then a `student.enrol` event)."""
        with self._tx() as db:
            added = db.execute(
                "INSERT OR IGNORE INTO course_enrolments (assignment_id, student, created_at) VALUES (?, ?, ?)",
                (aid, student, now),
            ).rowcount
            if added and by is not None:
                cid = db.execute("SELECT course_id FROM course_assignments WHERE id = ?", (aid,)).fetchone()[0]
                record(by, db, "student.enrol", Target(cid, aid, student=student), None, {"enrolled": True})

    def extend(
        self,
        aid: str,
        student: str,
        deadline: float | None,
        who: str = "",
        why: str = "",
        now: float = 0,
        by: By | None = None,
    ) -> bool:
        """Their own deadline (None: the assignment's), and the grant kept in its history (before, after, who,
        why, when); with `by`, an `extension` audit event: the deadline before and after (ISO 8601; null: the
        assignment's). One transaction."""
        with self._tx() as db:
            row = db.execute(
                "SELECT e.deadline, a.course_id FROM course_enrolments e JOIN course_assignments a"
                " ON a.id = e.assignment_id WHERE e.assignment_id = ? AND e.student = ?",
                (aid, student),
            ).fetchone()
            if row is None:
                return False
            db.execute(
                "UPDATE course_enrolments SET deadline = ? WHERE assignment_id = ? AND student = ?",
                (deadline, aid, student),
            )
            db.execute(
                "INSERT INTO course_extensions (assignment_id, student, before, after, who, why, at)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                (aid, student, row[0], deadline, who, why, now),
            )
            target = Target(row["course_id"], aid, student=student)
            record(by, db, "extension", target, {"deadline": iso(row[0])}, {"deadline": iso(deadline)})
        return True

    def extensions(self, aid: str, student: str) -> list[dict]:
        """A student's extensions of an assignment, oldest first."""
        rows = self.db.execute(
            "SELECT * FROM course_extensions WHERE assignment_id = ? AND student = ? ORDER BY at, rowid", (aid, student)
        )
        return [dict(r) for r in rows]

    # -- submissions ---------------------------------------------------------------------------

    def add_submission(
        self,
        sub: dict,
        max_attempts: int | None,
        per_hour: int,
        hour_ago: float,
        also: Callable[[sqlite3.Connection], object] | None = None,
        before: Callable[[sqlite3.Connection], dict] | None = None,
    ) -> str | None:
        """The submission's row, unless the student is past a cap: then which one ("attempts" or "hour"),
        with nothing written. Counting and writing are one transaction, so a burst cannot pass a cap. `also`
        writes more in the same transaction (its row in the grading run: then it is `handed` at once), so the
        two rows are kept together or neither is (a full disk). `before` reads what it needs in the same
        transaction and gives the row's last fields (the late tokens it spends: server/course/tokens.py), or
        raises to keep nothing."""
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
            if before is not None:
                sub.update(before(db))
            db.execute(
                "INSERT INTO course_submissions (id, assignment_id, student, version, run_id, kind, file,"
                " accepted_at, late, handed, tokens_spent) VALUES (:id, :assignment_id, :student, :version, :run_id,"
                " :kind, :file, :accepted_at, :late, :handed, :tokens_spent)",
                {"tokens_spent": 0, **sub, "handed": int(also is not None)},
            )
            if also is not None:
                also(db)
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

    def handed(self, sid: str, run_id: str) -> None:
        """Its row is in `run_id` (unless a regrade moved it to another run meanwhile: then it is handed again)."""
        self.db.execute("UPDATE course_submissions SET handed = 1 WHERE id = ? AND run_id = ?", (sid, run_id))

    def unhanded(self) -> list[dict]:
        """Submissions accepted but not yet in their grading run (a server stopped in between)."""
        rows = self.db.execute("SELECT * FROM course_submissions WHERE handed = 0 ORDER BY accepted_at")
        return [dict(r) for r in rows]

    def regrade(self, aid: str, version: int, run_id: str, by: By | None = None) -> list[dict]:
        """Every submission of the assignment moved to a new version's run, to be handed to it again. With `by`:
        a `regrade` event, the versions the submissions were graded under before (and how many) and the new one."""
        with self._tx() as db:
            if by is not None:
                rows = db.execute(
                    "SELECT version, COUNT(*) AS n FROM course_submissions WHERE assignment_id = ?"
                    " GROUP BY version ORDER BY version",
                    (aid,),
                ).fetchall()
                cid = db.execute("SELECT course_id FROM course_assignments WHERE id = ?", (aid,)).fetchone()[0]
                before = {"versions": {str(r["version"]): r["n"] for r in rows}}
                after = {"version": version, "submissions": sum(r["n"] for r in rows)}
                record(by, db, "regrade", Target(cid, aid), before, after)
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

    def submission_of(self, sid: str) -> tuple[str, str] | None:
        """(assignment, student) of a submission, by its id alone."""
        row = self.db.execute("SELECT assignment_id, student FROM course_submissions WHERE id = ?", (sid,)).fetchone()
        return (row[0], row[1]) if row else None

    def submission(self, aid: str, sid: str) -> dict | None:
        row = self.db.execute(
            "SELECT s.*, g.stage, g.status, g.score, g.max_score FROM course_submissions s LEFT JOIN grading_items g"
            " ON g.run_id = s.run_id AND g.student = s.id WHERE s.assignment_id = ? AND s.id = ?",
            (aid, sid),
        ).fetchone()
        return dict(row) if row else None


def _member_event(db: sqlite3.Connection, by: By, cid: str, r: dict, was: sqlite3.Row | None, enrol: list) -> None:
    """A roster row's event: the member added, or changed (their name, email, or on every assignment now)."""
    after = {"name": r["name"], "email": r["email"], "every": bool(r.get("every", 0)) or bool(was and was["every"])}
    aid = enrol[0] if len(enrol) == 1 and was is None else None
    if was is None:
        record(by, db, "student.add", Target(cid, aid, student=r["student"]), None, after)
        return
    before = {"name": was["name"], "email": was["email"], "every": bool(was["every"])}
    if before != after:
        record(by, db, "student.change", Target(cid, student=r["student"]), before, after)


def _version(row: sqlite3.Row) -> dict:
    out = dict(row)
    out["spec"], out["policy"] = json.loads(out["spec"]), json.loads(out["policy"])
    return out
