"""Who someone is in a course, as named values (their strings are what SQLite keeps and JSON carries).

- `Role`: the server's admin (the holder of TRACER_INSTRUCTOR_TOKEN), a course's instructor or TA (its staff), a
  student of its roster. server/course/people.py says what each may do; server/lti/roles.py reads an LMS's roles
  into these.
- `Kind`: whose a token is, a student's or a staff member's (the `kind` of the course's tokens and of the
  derived tokens' message, server/course/people.TokenMaker).

Compare against these, never against string literals: `who.role == Role.TA`, `row["kind"] == Kind.STAFF`.
"""

from __future__ import annotations

from enum import StrEnum


class Role(StrEnum):
    ADMIN = "admin"
    INSTRUCTOR = "instructor"
    TA = "ta"
    STUDENT = "student"


STAFF = (Role.INSTRUCTOR, Role.TA)  # a course's staff: the roles a staff member may be given


class Kind(StrEnum):
    STUDENT = "student"
    STAFF = "staff"
