"""The dashboard's LMS line in Chromium (issue #31's grades back): the course linked to a test LMS
(tests/support/lti_platform.py; the fixtures `tool` and `lms` of tests/support/lms.py), a student's launch and
graded submission while the LMS is down; /course shows the grade waiting with the LMS's answer, then, the LMS back
and the score sent, the grade sent and no waiting line. Screenshots go to $WEB_SHOTS (course-lms-*.png)."""

from __future__ import annotations

from datetime import timedelta

from server.course.lms_store import LmsStore
from tests.support.api import INSTRUCTOR, bearer, wait_for
from tests.support.axe import assert_accessible
from tests.support.lms import EXAMPLE, T0
from tests.support.lti_platform import LEARNER
from tests.support.page import CSP_WATCH, DESKTOP, SHOTS


def stat(page, name: str) -> str:
    """The number the dashboard's Scores panel shows for `name` (its <dd>)."""
    return page.locator(f"[data-stat={name}] dd").inner_text().strip()


def test_web_course_lms_the_dashboard_says_grades_wait_for_the_lms_and_then_that_they_were_sent(tool, lms, browser):
    url, app, client = tool
    p, aid = lms
    r = p.do_launch(client, url, sub="student-9", roles=[LEARNER], custom={"assignment": aid})
    token = r.headers["location"].split("#token=")[1]
    p.down = True
    scene = (EXAMPLE / "class" / "alice.json").read_text()
    r = client.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(token))
    assert r.status_code == 202, r.text
    sub = r.headers["location"]
    wait_for(lambda: client.get(sub, headers=bearer(token)).json()["status"] == "graded", 300, "the grade", 0.5)
    store = LmsStore(app.state.settings.data_dir)
    wait_for(lambda: store.scores(aid)["error"], 60, "a failed post of the score", 0.2)

    context = browser.new_context(viewport=DESKTOP)
    context.add_init_script(CSP_WATCH)
    errors: list[str] = []
    try:
        page = context.new_page()
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(f"{url}/course#token={INSTRUCTOR}&open={aid}")
        page.wait_for_selector("#lms-note")
        note = page.locator("#lms-note")
        wait_for(lambda: "Grades wait" in note.inner_text() or page.wait_for_timeout(50), 30, "the waiting line")
        text = note.inner_text()
        assert "In the LMS: course-1 (" in text and "503" in text and "the next try:" in text, text
        assert (stat(page, "lms_pending"), stat(page, "lms_sent")) == ("1", "0")
        SHOTS.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(SHOTS / "course-lms-waiting.png"), full_page=True)

        p.down = False
        app.state.clock.now = T0 + timedelta(hours=3)
        app.state.lms.poster.wake()
        wait_for(lambda: any(s["userId"] == "student-9" for s in p.scores), 60, "the score at the LMS", 0.2)
        page.reload()
        page.wait_for_selector("#lms-note")
        wait_for(lambda: "Grades wait" not in page.locator("#lms-note").inner_text() or page.wait_for_timeout(50),
                 30, "the waiting line gone")  # fmt: skip
        assert (stat(page, "lms_pending"), stat(page, "lms_sent")) == ("0", "1")
        page.screenshot(path=str(SHOTS / "course-lms-sent.png"), full_page=True)
        assert not errors, errors
    finally:
        context.close()


def test_web_course_lms_a_refused_grade_is_listed_with_why_and_sent_again_and_an_inactive_student_marked(
    tool, lms, browser
):
    """A score the LMS refused for good (HTTP 422) is listed on the dashboard with the LMS's status and reason;
    "Send again" queues it and it reaches the LMS; a student gone from the LMS course shows as inactive in the
    class's table. axe on the refused grades' box."""
    url, app, client = tool
    p, aid = lms
    r = p.do_launch(client, url, sub="student-12", roles=[LEARNER], custom={"assignment": aid})
    assert r.status_code == 303, r.text
    course = app.state.course
    gone = course.store.by_lti("gfx", "student", f"{p.registered_id}:student-12")["student"]
    course.store.set_left("gfx", [gone], course.now())
    lms_ = app.state.lms
    row = {"platform_id": p.registered_id, "lineitem": f"{p.url}/lineitems/li-1", "user_id": "student-12",
           "assignment_id": aid, "student": gone, "score_given": 8.0, "score_max": 13.0}  # fmt: skip
    p.refuse = (422, "invalid_score")
    try:
        assert lms_.store.add_score(row, lms_.now())
        lms_.poster.wake()
        wait_for(lambda: lms_.store.scores(aid)["failed"], 60, "the refused score", 0.2)
    finally:
        p.refuse = None

    context = browser.new_context(viewport=DESKTOP)
    context.add_init_script(CSP_WATCH)
    errors: list[str] = []
    try:
        page = context.new_page()
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(f"{url}/course#token={INSTRUCTOR}&open={aid}")
        box = page.locator("#lms-refused")
        box.wait_for()
        text = box.inner_text()
        assert "Grades the LMS refused (1)" in text and gone in text and "HTTP 422" in text, text
        assert "invalid_score" in text, text
        badge = page.locator(f'tr[data-student="{gone}"] .badge.inactive')
        badge.wait_for()
        assert badge.inner_text() == "inactive"
        assert_accessible(page, "the refused grades of the LMS", "#lms-refused")
        SHOTS.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(SHOTS / "course-lms-refused.png"), full_page=True)
        page.locator("#lms-send-again").click()
        wait_for(lambda: "queued to be sent to the LMS again" in page.locator("#board-status").inner_text()
                 or page.wait_for_timeout(50), 30, "the send again's answer")  # fmt: skip
        wait_for(lambda: any(s["userId"] == "student-12" for s in p.scores), 60, "the score at the LMS", 0.2)
        page.locator("#lms-refused").wait_for(state="detached")
        assert not errors, errors
    finally:
        context.close()
