"""The typed rows of the course's remaining tables (server/course/schema.py): each names the columns of its table
(PRAGMA table_info), or of what its store's read makes of them, and the store's reads return exactly those keys,
so that the type checker knows the keys the service reads. (Courses, staff, members, students, assignments,
versions and submissions: tests/server/course/test_course.py.)"""

from __future__ import annotations

from server.course import audit
from server.course import regrade_store as rs
from server.course.audit import By, Target
from server.course.schema import (
    AuditEvent,
    ExtensionRow,
    ManualGrade,
    ManualGradeRow,
    ManualRow,
    OverrideRow,
    RegradeEvent,
    RegradeRequestRow,
    TokenGrantRow,
    TokenRow,
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


def test_course_token_and_extension_rows_are_typed_with_the_columns_the_store_returns(tmp_path):
    """`TokenRow` names each column of `course_tokens` (token), `TokenGrantRow` of `course_token_grants`
    (token_grants), `ExtensionRow` of `course_extensions` (extensions)."""
    store = CourseStore(tmp_path)
    assert set(TokenRow.__required_keys__) == columns(store, "course_tokens")
    assert set(TokenGrantRow.__required_keys__) == columns(store, "course_token_grants")
    assert set(ExtensionRow.__required_keys__) == columns(store, "course_extensions")
    store.create(AID, '{"name": "hw"}', {}, "r" * 32, 1.0)
    store.add_members(DEFAULT_COURSE, [{"student": "ann", "name": "Ann", "email": "a@x"}], 2.0, [AID])
    store.keep_token(DEFAULT_COURSE, "student", "ann", "h-ann", 2.0)
    token = store.token("h-ann")
    assert token is not None
    assert set(token) == set(TokenRow.__required_keys__)
    store.db.execute(  # a grant as Tokens.grant_tokens writes it (server/course/tokens.py)
        "INSERT INTO course_token_grants (course_id, student, added, before, after, who, why, at)"
        " VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        (DEFAULT_COURSE, "ann", 2, 0, 2, "bo", "ill", 3.0),
    )
    assert [set(g) for g in store.token_grants(DEFAULT_COURSE, "ann")] == [set(TokenGrantRow.__required_keys__)]
    assert store.extend(AID, "ann", 99.0, "bo", "ill", 4.0)
    assert [set(e) for e in store.extensions(AID, "ann")] == [set(ExtensionRow.__required_keys__)]


def test_course_audit_events_are_typed_with_the_keys_the_trail_returns(tmp_path):
    """`AuditEvent` names what audit.events makes of a `course_audit` row: its columns but the course,
    assignment and student (the target's), `at` in ISO 8601, before, after and the target parsed."""
    store = CourseStore(tmp_path)
    table = columns(store, "course_audit")
    assert set(AuditEvent.__required_keys__) == table - {"course_id", "assignment_id", "student"}
    store.set_late_tokens(DEFAULT_COURSE, 3, By("admin", 1.0, "a week"))
    (event,) = audit.events(store.db, DEFAULT_COURSE)
    assert set(event) == set(AuditEvent.__required_keys__)
    assert (event["at"], event["target"], event["after"]) == ("1970-01-01T00:00:01Z", {"course": "default"},
                                                             {"late_tokens": 3})  # fmt: skip
