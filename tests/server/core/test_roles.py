"""Roles and token kinds as enums (server/core/roles.py): their strings are what SQLite keeps and JSON carries, so
they never change, and an enum member is its string wherever one is compared, stored or sent."""

from __future__ import annotations

import json
import sqlite3

from server.core.roles import STAFF, Kind, Role
from server.course.people import ROLES, Who
from server.lti.roles import course_role


def test_roles_keep_their_strings():
    assert [r.value for r in Role] == ["admin", "instructor", "ta", "student"]
    assert [k.value for k in Kind] == ["student", "staff"]
    assert STAFF == ROLES == ("instructor", "ta")


def test_roles_are_their_strings_in_json_in_sqlite_and_in_comparisons():
    assert json.dumps({"role": Role.TA, "kind": Kind.STAFF}) == '{"role": "ta", "kind": "staff"}'
    db = sqlite3.connect(":memory:")
    db.execute("CREATE TABLE t (role TEXT)")
    db.execute("INSERT INTO t VALUES (?)", (Role.INSTRUCTOR,))
    assert db.execute("SELECT role, typeof(role) FROM t").fetchone() == ("instructor", "text")
    assert Role("ta") is Role.TA and "ta" in STAFF and "student" not in STAFF
    assert f"{Role.STUDENT}" == "student"
    assert ", ".join(STAFF) == "instructor, ta"


def test_roles_a_launch_and_who_speak_the_enum():
    assert course_role(["http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"]) is Role.STUDENT
    assert course_role(["TeachingAssistant", "Instructor"]) is Role.TA
    assert Who().role is Role.INSTRUCTOR and Who(None, Role.TA).may("follow") and not Who(None, Role.TA).may("publish")
