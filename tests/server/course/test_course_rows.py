"""The typed rows of the course's remaining tables (server/course/schema.py): each names the columns of its table
(PRAGMA table_info), or of what its store's read makes of them, and the store's reads return exactly those keys,
so that the type checker knows the keys the service reads. (Courses, staff, members, students, assignments,
versions and submissions: tests/server/course/test_course.py.)"""

from __future__ import annotations

from server.course import regrade_store as rs
from server.course.audit import By, Target
from server.course.schema import (
    ManualGrade,
    ManualGradeRow,
    ManualRow,
    OverrideRow,
    RegradeEvent,
    RegradeRequestRow,
)
from server.course.store import DEFAULT_COURSE, CourseStore

AID, SID = "a" * 32, "s" * 32


def columns(store: CourseStore, table: str) -> set[str]:
    return {r["name"] for r in store.db.execute(f"PRAGMA table_info({table})")}


def test_course_regrade_rows_are_typed_with_the_columns_the_store_returns(tmp_path):
    """`RegradeRequestRow` names each column of `course_regrade_requests` (create, one, of_assignment);
    `RegradeEvent` a `course_regrade_events` row as events returns it (at, who, kind and its change's keys);
    `OverrideRow` what overrides returns of a `course_test_overrides` row (version, original, points)."""
    store = CourseStore(tmp_path)
    assert set(RegradeRequestRow.__required_keys__) == columns(store, "course_regrade_requests")
    req = {"assignment_id": AID, "submission_id": SID, "student": "ann", "item": "validity", "kind": "test",
           "reason": "why", "points": 0.0}  # fmt: skip
    target = Target(DEFAULT_COURSE, AID, student="ann", submission=SID)
    row = rs.create(store, req, target, By("student:ann", 1.0))
    assert row is not None
    assert set(row) == set(RegradeRequestRow.__required_keys__)
    assert rs.create(store, req, target, By("student:ann", 1.5)) is None  # one open request per item
    points = {"before": 0.0, "after": 1.0, "test": {"version": 1, "original": 0.0}}
    rs.answer(store, row["id"], rs.ACCEPTED, "yes", points, target, By("ta:bo", 2.0))
    one = rs.one(store, row["id"])
    assert one is not None
    assert set(one) == set(RegradeRequestRow.__required_keys__)
    assert [set(r) for r in rs.of_assignment(store, AID)] == [set(RegradeRequestRow.__required_keys__)]

    required, optional = RegradeEvent.__required_keys__, RegradeEvent.__optional_keys__
    assert required - {"status"} < columns(store, "course_regrade_events")  # status: every change's
    assert required == {"at", "who", "kind", "status"}
    assert optional == {"reason", "reply", "points", "points_before"}
    asked, answered = rs.events(store, [row["id"]])[row["id"]]
    assert set(asked) == required | {"reason", "points"}
    assert set(answered) == required | {"reply", "points", "points_before"}

    assert set(OverrideRow.__required_keys__) < columns(store, "course_test_overrides")
    found = rs.overrides(store, AID)
    assert set(found[SID]["validity"]) == set(OverrideRow.__required_keys__)
    assert set(rs.overrides(store, AID, SID)[SID]["validity"]) == set(OverrideRow.__required_keys__)


def test_course_manual_rows_are_typed_with_the_columns_the_store_returns(tmp_path):
    """`ManualGradeRow` names each column of `course_manual_grades` (manual_grades, its rubric parsed), of which
    `ManualGrade` is what a grader gives (set_manual's row); `ManualRow` each column of `course_manual`
    (manual_state, before the assignment has a row and after)."""
    store = CourseStore(tmp_path)
    assert set(ManualGradeRow.__required_keys__) == columns(store, "course_manual_grades")
    assert set(ManualGrade.__required_keys__) == {"rubric", "points", "comment", "grader"}
    assert set(ManualRow.__required_keys__) == columns(store, "course_manual")
    assert set(store.manual_state(AID)) == set(ManualRow.__required_keys__)  # no row yet
    grade: ManualGrade = {"rubric": ["good"], "points": None, "comment": "", "grader": "bo"}
    store.set_manual(AID, SID, "style", grade, 1.0)
    found = store.manual_grades(AID)
    assert set(found[SID]["style"]) == set(ManualGradeRow.__required_keys__)
    assert found[SID]["style"]["rubric"] == ["good"]
    assert set(store.manual_grades(AID, SID)[SID]["style"]) == set(ManualGradeRow.__required_keys__)
    store.release_manual(AID, "bo", 2.0)
    store.set_anonymous(AID, True)
    assert set(store.manual_state(AID)) == set(ManualRow.__required_keys__)
