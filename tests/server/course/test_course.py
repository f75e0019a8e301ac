"""The course's store and rules without the app (server/course/): attempts as the grading rows say, the
caps counted with the write, the roster's CSV, deadlines moved by an extension."""

from __future__ import annotations

import pytest

from server.core.errors import Invalid
from server.core.migrations import migrate
from server.course.roster import parse_roster
from server.course.schema import (
    AssignmentRow,
    CourseRow,
    MemberRow,
    StaffRow,
    StudentRow,
    SubmissionRow,
    SubmissionWithGrade,
    VersionRow,
)
from server.course.service import Course
from server.course.store import DEFAULT_COURSE, CourseStore
from server.grading.store import GradingStore


def sub(sid: str, at: float, student: str = "s1") -> dict:
    return {"id": sid, "assignment_id": "a" * 32, "student": student, "version": 1, "run_id": "r" * 32,
            "kind": "scene", "file": f"{sid}.json", "accepted_at": at, "late": 0}  # fmt: skip


def test_course_a_pending_submission_holds_its_attempt_until_graded_invalid(tmp_path):
    store, gs = CourseStore(tmp_path), GradingStore(tmp_path)
    gs.create_run("r" * 32, "{}", "hw", 13, [], open_=True)
    assert store.add_submission(sub("x1", 100.0), max_attempts=1, per_hour=10, hour_ago=0) is None
    assert store.attempts("a" * 32, "s1") == 1  # queued: holds it
    assert store.add_submission(sub("x2", 101.0), max_attempts=1, per_hour=10, hour_ago=0) == "attempts"
    gs.add_item("r" * 32, {"student": "x1", "kind": "scene", "filename": "s.json", "file": "x1.json"})
    gs.update_item("r" * 32, "x1", stage="graded", status="invalid", score=0.0, max_score=13.0)
    assert store.attempts("a" * 32, "s1") == 0  # found invalid: given back
    assert store.add_submission(sub("x2", 102.0), max_attempts=1, per_hour=10, hour_ago=0) is None
    assert [s["id"] for s in store.submissions("a" * 32)] == ["x1", "x2"]


def test_course_the_hourly_cap_counts_the_last_hour_only(tmp_path):
    store = CourseStore(tmp_path)
    for i in range(3):
        assert store.add_submission(sub(f"h{i}", 1000.0 + i), None, per_hour=3, hour_ago=0) is None
    assert store.add_submission(sub("h3", 1003.0), None, per_hour=3, hour_ago=1003.0 - 3600) == "hour"
    assert store.add_submission(sub("h3", 4601.5), None, per_hour=3, hour_ago=4601.5 - 3600) is None
    assert store.add_submission(sub("o1", 1003.0, student="s2"), None, per_hour=3, hour_ago=0) is None  # per student


def test_course_a_handed_twice_submission_is_one_grading_row(tmp_path):
    gs = GradingStore(tmp_path)
    gs.create_run("r" * 32, "{}", "hw", 13, [], open_=True)
    it = {"student": "x1", "kind": "scene", "filename": "s.json", "file": "x1.json"}
    assert gs.add_item("r" * 32, it) is True
    assert gs.add_item("r" * 32, it) is False
    assert [i["student"] for i in gs.items("r" * 32)] == ["x1"] and gs.is_open("r" * 32)


def test_course_roster_rows_and_errors():
    rows = parse_roster('\ufeffID, Name ,Email\ns1,Zoë O\'Brien,z@x.edu\n\ns2,"Doe, Jane",\n')
    assert rows == [{"student": "s1", "name": "Zoë O'Brien", "email": "z@x.edu"},
                    {"student": "s2", "name": "Doe, Jane", "email": ""}]  # fmt: skip
    with pytest.raises(Invalid) as e:
        parse_roster("id,name,email\n.x,X,\n")
    assert e.value.errors[0]["path"] == "line 2.id"


def test_course_an_extension_moves_the_deadline_and_the_late_cut_off_alike():
    a = {"policy": {"deadline": "2026-12-03T12:00:00+00:00", "late_until": "2026-12-04T12:00:00+00:00"}}
    due, cut = Course.deadlines(a, None)
    assert cut - due == 86400
    ext = {"deadline": due + 3600}
    assert Course.deadlines(a, ext) == (due + 3600, cut + 3600)
    a["policy"]["late_until"] = None
    assert Course.deadlines(a, ext) == (due + 3600, due + 3600)


OLD_SCHEMA = """
CREATE TABLE course_assignments (id TEXT PRIMARY KEY, version INTEGER NOT NULL, created_at REAL NOT NULL);
CREATE TABLE course_students (
    assignment_id TEXT NOT NULL, student TEXT NOT NULL, name TEXT NOT NULL, email TEXT NOT NULL DEFAULT '',
    token_hash TEXT NOT NULL UNIQUE, self_declared INTEGER NOT NULL DEFAULT 0, deadline REAL,
    created_at REAL NOT NULL, PRIMARY KEY (assignment_id, student));
"""


def test_course_data_from_before_courses_moves_into_the_default_course_nothing_lost(tmp_path):
    """The roster of before courses (a token per student per assignment) -> the default course: each student
    once (their latest name), every old token still opening its assignment, the extensions kept."""
    import sqlite3

    db = sqlite3.connect(tmp_path / "jobs.sqlite3")
    db.executescript(OLD_SCHEMA)
    a1, a2 = "1" * 32, "2" * 32
    db.executemany("INSERT INTO course_assignments VALUES (?, 1, ?)", [(a1, 1.0), (a2, 2.0)])
    db.executemany(
        "INSERT INTO course_students VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        [(a1, "ann", "Ann", "ann@x", "h-ann-1", 0, None, 10.0), (a1, "bo", "Bo", "", "h-bo-1", 0, 99.0, 11.0),
         (a2, "ann", "Ann B.", "ann@y", "h-ann-2", 0, None, 20.0),
         (a2, "joe-1a2b3c", "Joe", "", "h-joe", 1, None, 21.0)],
    )  # fmt: skip
    db.commit()
    db.close()
    migrate(tmp_path)  # as a server's start does (version 0 -> the latest)
    store = CourseStore(tmp_path, now=50.0)
    assert [c["id"] for c in store.courses()] == ["default"]
    assert [(m["student"], m["name"], m["email"], m["self_declared"]) for m in store.members("default")] == [
        ("ann", "Ann B.", "ann@y", 0), ("bo", "Bo", "", 0), ("joe-1a2b3c", "Joe", "", 1),
    ]  # fmt: skip
    assert [s["student"] for s in store.students(a1)] == ["ann", "bo"]  # each assignment's roster as it was
    assert [s["student"] for s in store.students(a2)] == ["ann", "joe-1a2b3c"]
    assert store.student(a1, "bo")["deadline"] == 99.0
    assert store.by_token(a1, "h-ann-1")["student"] == "ann" and store.by_token(a2, "h-ann-2")["student"] == "ann"
    assert store.by_token(a2, "h-ann-1")["student"] == "ann"  # one identity in the course now
    assert store.by_token(a1, "h-joe") is None  # joined the open one only
    assert store.assignment(a1) is None or store.assignment(a1)["course_id"] == "default"
    tables = {r[0] for r in store.db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    assert "course_students" not in tables
    migrate(tmp_path)
    CourseStore(tmp_path, now=60.0)  # a second start changes nothing
    assert len(store.members("default")) == 3


def test_course_rows_are_typed_with_every_column_of_their_tables(tmp_path):
    """`CourseRow` and `StaffRow` (server/course/schema.py: what the store's course and staff reads return) name
    each column of their tables and no other, so that the type checker knows the keys the service reads."""
    store = CourseStore(tmp_path)
    for table, row in (("courses", CourseRow), ("course_staff", StaffRow)):
        columns = {r["name"] for r in store.db.execute(f"PRAGMA table_info({table})")}
        assert set(row.__required_keys__) == columns, table
    store.add_staff(DEFAULT_COURSE, {"person": "ta1", "name": "A TA", "role": "ta"}, 1.0)
    assert set(store.course(DEFAULT_COURSE)) == set(CourseRow.__required_keys__)
    assert set(store.staff_member(DEFAULT_COURSE, "ta1")) == set(StaffRow.__required_keys__)
    assert [set(r) for r in store.staff(DEFAULT_COURSE)] == [set(StaffRow.__required_keys__)]


def test_course_member_and_roster_student_rows_are_typed_with_the_columns_the_store_returns(tmp_path):
    """`MemberRow` names each column of `course_members`; `StudentRow` each column of the roster's join (an
    enrolment with its member: RosterTables' STUDENT), what members/member and students/student/by_token return."""
    store = CourseStore(tmp_path)
    columns = {r["name"] for r in store.db.execute("PRAGMA table_info(course_members)")}
    assert set(MemberRow.__required_keys__) == columns
    aid = "a" * 32
    store.create(aid, '{"name": "hw"}', {}, "r" * 32, 1.0)
    store.add_members(DEFAULT_COURSE, [{"student": "ann", "name": "Ann", "email": "a@x"}], 2.0, [aid])
    store.keep_token(DEFAULT_COURSE, "student", "ann", "h-ann", 2.0)
    assert set(store.member(DEFAULT_COURSE, "ann")) == set(MemberRow.__required_keys__)
    assert [set(m) for m in store.members(DEFAULT_COURSE)] == [set(MemberRow.__required_keys__)]
    assert set(store.student(aid, "ann")) == set(StudentRow.__required_keys__)
    assert [set(s) for s in store.students(aid)] == [set(StudentRow.__required_keys__)]
    assert set(store.by_token(aid, "h-ann")) == set(StudentRow.__required_keys__)


def test_course_assignment_and_version_rows_are_typed_with_the_columns_the_store_returns(tmp_path):
    """`AssignmentRow` names each column of `course_assignments` and of its current `course_versions` row (the
    version's `assignment_id` as `id`, its `created_at` as `version_at`), `VersionRow` a version's: what
    assignment and versions return, spec and policy parsed."""
    store = CourseStore(tmp_path)

    def columns(table: str) -> set[str]:
        return {r["name"] for r in store.db.execute(f"PRAGMA table_info({table})")}

    version = {"id", "version_at"} | columns("course_versions") - {"assignment_id", "created_at"}
    assert set(VersionRow.__required_keys__) == version
    assert set(AssignmentRow.__required_keys__) == version | columns("course_assignments")
    aid = "a" * 32
    store.create(aid, '{"name": "hw"}', {"deadline": "2026-01-01T00:00:00+00:00"}, "r" * 32, 1.0)
    store.add_version(aid, '{"name": "hw"}', {}, "q" * 32, 2.0)
    a = store.assignment(aid)
    assert set(a) == set(AssignmentRow.__required_keys__)
    assert (a["spec"], a["policy"], a["version"], a["version_at"]) == ({"name": "hw"}, {}, 2, 2.0)
    assert [set(v) for v in store.versions(aid)] == [set(VersionRow.__required_keys__)] * 2


def test_course_submission_rows_are_typed_with_the_columns_the_store_returns(tmp_path):
    """`SubmissionRow` names each column of `course_submissions` (what unhanded and regrade return);
    `SubmissionWithGrade` those and its grading row's stage, status, score and max_score (submissions,
    submission), `auto_score` only where a regrade request moved the score."""
    store = CourseStore(tmp_path)
    columns = {r["name"] for r in store.db.execute("PRAGMA table_info(course_submissions)")}
    assert set(SubmissionRow.__required_keys__) == columns
    graded = columns | {"stage", "status", "score", "max_score"}
    assert set(SubmissionWithGrade.__required_keys__) == graded
    assert SubmissionWithGrade.__optional_keys__ == {"auto_score"}
    assert store.add_submission(sub("x1", 100.0), None, per_hour=10, hour_ago=0) is None
    assert [set(s) for s in store.unhanded()] == [columns]
    assert [set(s) for s in store.submissions("a" * 32)] == [graded]
    assert set(store.submission("a" * 32, "x1")) == graded
    assert [set(s) for s in store.regrade("a" * 32, 2, "q" * 32)] == [columns]
