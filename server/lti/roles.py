"""A launch's roles -> the user's role in the course: "instructor", "ta", "student" or None.

Platforms send LIS role URIs (LTI 1.3 §A.2: `http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor`),
some the LTI 1.1 URNs (`urn:lti:role:ims/lis/Instructor`) or the short names (`Instructor`, `Learner`).
Context roles decide, plus the institution's and the system's administrators; an institution role such as
`institution/person#Instructor` (a member of staff) makes no one an instructor of this course. A Mentor, an
observer or anyone else gets None. Instructor beats teaching assistant beats student, except that the principal
role `membership#Instructor` which the specification asks platforms to send beside the sub-role
`membership/Instructor#TeachingAssistant` leaves a teaching assistant a teaching assistant.
"""

from __future__ import annotations

from server.core.roles import Role

LIS = "http://purl.imsglobal.org/vocab/lis/v2/"
MEMBERSHIP = LIS + "membership"
URN = "urn:lti:role:ims/lis/"

PRINCIPAL_INSTRUCTOR = {MEMBERSHIP + "#Instructor", URN + "Instructor", "Instructor"}
INSTRUCTOR = PRINCIPAL_INSTRUCTOR | {
    MEMBERSHIP + "#Administrator",
    MEMBERSHIP + "#ContentDeveloper",
    MEMBERSHIP + "/Instructor#PrimaryInstructor",
    MEMBERSHIP + "/Instructor#Lecturer",
    LIS + "institution/person#Administrator",
    LIS + "system/person#Administrator",
    LIS + "system/person#SysAdmin",
    URN + "Administrator",
    URN + "ContentDeveloper",
    "urn:lti:instrole:ims/lis/Administrator",
    "urn:lti:sysrole:ims/lis/SysAdmin",
    "Administrator",
    "ContentDeveloper",
}
TA = {
    MEMBERSHIP + "/Instructor#TeachingAssistant",
    MEMBERSHIP + "#TeachingAssistant",
    URN + "TeachingAssistant",
    URN + "Instructor/TeachingAssistant",
    "TeachingAssistant",
}
STUDENT = {
    MEMBERSHIP + "#Learner",
    MEMBERSHIP + "/Learner#Learner",
    URN + "Learner",
    URN + "Learner/Learner",
    "Learner",
}


def course_role(roles: list[str] | None) -> Role | None:
    """The course role of a launch's (or a member's) `roles`: "instructor", "ta", "student" or None."""
    have = {r.strip() for r in roles or () if isinstance(r, str)}
    if have & TA:
        have -= PRINCIPAL_INSTRUCTOR  # the principal role sent beside the TA's sub-role
    if have & INSTRUCTOR:
        return Role.INSTRUCTOR
    if have & TA:
        return Role.TA
    if have & STUDENT:
        return Role.STUDENT
    return None
