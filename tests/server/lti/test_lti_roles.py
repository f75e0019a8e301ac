"""Role URIs -> the course's role."""

from __future__ import annotations

import pytest

from server.lti.roles import course_role

M = "http://purl.imsglobal.org/vocab/lis/v2/membership"
I = "http://purl.imsglobal.org/vocab/lis/v2/institution/person"


@pytest.mark.parametrize(
    "roles, role",
    [
        ([M + "#Instructor"], "instructor"),
        ([M + "#Administrator"], "instructor"),
        ([I + "#Administrator"], "instructor"),
        ([M + "#ContentDeveloper"], "instructor"),
        ([M + "/Instructor#TeachingAssistant"], "ta"),
        ([M + "#TeachingAssistant"], "ta"),
        ([M + "#Instructor", M + "/Instructor#TeachingAssistant"], "ta"),  # the principal role beside the sub-role
        ([M + "#Learner"], "student"),
        ([M + "/Learner#Learner"], "student"),
        (["Instructor"], "instructor"),
        (["Learner"], "student"),
        (["urn:lti:role:ims/lis/TeachingAssistant"], "ta"),
        ([M + "#Learner", M + "#Administrator"], "instructor"),
        ([M + "#Learner", M + "/Instructor#TeachingAssistant"], "ta"),
        ([M + "#Mentor"], None),
        ([I + "#Instructor"], None),  # staff at the institution, not this course's instructor
        ([I + "#Student"], None),
        ([], None),
    ],
)
def test_lti_roles_course_role(roles, role):
    assert course_role(roles) == role
