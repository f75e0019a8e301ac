"""/course for the people it is for (issue #42): the admin's new course becomes the one the publish form publishes
into (it stayed on the first); a TA's page says "Your TA token", not "Instructor token", and shows none of the
forms the server refuses a TA (the roster and its links, a replaced link, a new version), each place saying why;
before a token, the page tells a person what to do, not "send 'Authorization: Bearer <token>'". Uses the
fixtures of tests/web/conftest.py and the course page's helpers of test_web_course_instructor.py."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import httpx

from tests.support.api import INSTRUCTOR, bearer
from tests.support.axe import assert_accessible
from tests.support.course_page import CoursePage, open_course
from tests.support.dashboard import small_spec
from tests.support.page import DESKTOP, SHOTS


def test_web_course_publish_into_follows_a_new_course_and_a_ta_sees_only_what_a_ta_may_do(browser, server, tmp_path):
    p = open_course(browser, server, tmp_path)
    page = p.page
    page.wait_for_selector("#course-form")
    page.fill("#new-course-id", "staff-201")
    page.fill("#new-course-name", "Rendering 201")
    page.click("#course-form button[type=submit]")
    page.wait_for_selector("#course-list li[data-id=staff-201]")
    assert page.input_value("#course-into") == "staff-201"  # the new course, not the first one
    assert page.input_value("#staff-course") == "staff-201"
    page.fill("#staff-id", "tam")
    page.fill("#staff-name", "Tam TA")
    page.select_option("#staff-role", "ta")
    page.click("#staff-form button[type=submit]")
    page.wait_for_selector("#staff-link")
    link = page.text_content("#staff-link")
    p.context.close()
    assert p.unexpected_errors() == []

    # an assignment of the course, published by the admin
    deadline = (datetime.now(UTC) + timedelta(days=7)).isoformat()
    with httpx.Client(base_url=server.url, timeout=60, headers=bearer(INSTRUCTOR)) as http:
        r = http.post("/api/courses/staff-201/assignments", json={"spec": small_spec(), "deadline": deadline})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]

    # the TA opens their link: their token is named as theirs, the forms a TA may not use are not there
    ta = CoursePage(browser, server, DESKTOP)
    page = ta.page
    page.goto(link)
    page.wait_for_selector("#course-role")
    assert page.text_content('label[for="course-token"]') == "Your TA token"
    assert "Instructor token" not in page.inner_text("body")
    assert page.locator("#h-publish").count() == 0
    page.goto(f"{server.url}/course#{aid}")
    page.wait_for_selector("#roster-ta")
    assert page.locator("#roster-file, #links-again, #links-reissue, #edit-box").count() == 0
    assert "As a TA you follow the class, grant extensions and regrade." in page.text_content("#roster-ta")
    assert "the instructors'" in page.text_content("#edit-ta")
    assert page.text_content('label[for="course-token"]') == "Your TA token"
    page.screenshot(path=str(SHOTS / "course-ta-board.png"), full_page=True)
    assert_accessible(page, "a TA's dashboard")
    ta.context.close()
    assert ta.unexpected_errors() == []


def test_web_course_before_a_token_says_what_to_do(browser, server):
    """No token yet: the page says to open the staff link or paste a token, in words, and not in HTTP's."""
    p = CoursePage(browser, server, DESKTOP)
    p.allow.append(r"status of 401")  # the page's first request, before a token, is refused
    page = p.page
    page.goto(f"{server.url}/course")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    page.wait_for_function("() => document.querySelector('#course-access-status').dataset.kind === 'error'")
    words = page.inner_text("main")
    assert "Authorization" not in words and "Bearer" not in words, words
    status = page.text_content("#course-access-status")
    assert "Open the staff link you were sent" in status and "paste your token above" in status, status
    assert page.text_content("#list-status") == "Sign in first: see above."
    p.context.close()
    assert p.unexpected_errors() == []
