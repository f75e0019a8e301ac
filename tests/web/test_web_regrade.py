"""Regrade requests on the pages (web/js/course/regrade.js, issue #41 item 3) in Chromium: the statistics tests'
small assignment, bea's red-sky scene without the glass graded by the conftest server's render worker. Bea asks
from her assignment page ("Request a regrade" beside the glass requirement, a reason, Send) with the keyboard; the
instructor answers in the dashboard's "Regrade requests" panel (a reply, a point, Accept); bea's page then shows
the answer, and grades.csv the new score. axe finds no serious violation in either part."""

from __future__ import annotations

import csv
import io
import json

import httpx
import pytest

from tests.support.api import bearer, wait_for
from tests.support.axe import assert_accessible
from tests.support.course_page import CoursePage, open_course
from tests.support.dashboard import good_scene
from tests.support.page import DESKTOP, TEACHER
from tests.support.stats import red, small_spec

DEADLINE = "2100-01-01T12:00:00Z"
GLASS = "a glass object"


@pytest.fixture(scope="module")
def assignment(server) -> tuple[str, str, str]:
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        r = c.post("/api/assignments", json={"spec": small_spec(), "deadline": DEADLINE})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        r = c.post(f"/api/assignments/{aid}/roster", content="id,name,email\nbea,Bea B,\n",
                   headers={"Content-Type": "text/csv"})  # fmt: skip
        assert r.status_code == 200, r.text
        token = r.json()["students"][0]["token"]
        r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": red(glass=False)}, headers=bearer(token))
        assert r.status_code == 202, r.text
        sid = r.json()["id"]
        url = f"/api/assignments/{aid}/submissions/{sid}"
        wait_for(lambda: c.get(url).json()["status"] == "graded", 240, f"{sid} graded", 0.2)
    return aid, sid, token


def test_web_regrade_a_student_asks_the_instructor_answers_the_student_sees_it(browser, server, assignment, tmp_path):
    aid, sid, token = assignment
    me = CoursePage(browser, server, DESKTOP)
    p = None
    try:
        bea = me.page
        bea.goto(f"{server.url}/assignments/{aid}#token={token}")
        row = bea.locator(f"#a-sub-list li[data-id='{sid}']")
        ask = row.locator(f"button.a-regrade-ask[data-item='{GLASS}']")
        ask.wait_for()
        assert ask.get_attribute("aria-label") == f"Request a regrade of {GLASS}"
        ask.focus()
        bea.keyboard.press("Enter")
        reason = row.locator("form.a-regrade-form textarea")
        reason.wait_for()
        assert bea.evaluate("() => document.activeElement.tagName") == "TEXTAREA"  # the form has the focus
        bea.keyboard.type("My ball has kt 0.9: it is glass")
        bea.keyboard.press("Tab")  # to Send
        bea.keyboard.press("Enter")
        bea.wait_for_function("() => document.querySelector('.a-regrade-status')?.textContent.startsWith('Sent')")
        row.locator(".a-regrade-req[data-status='open']").wait_for()
        assert ask.is_disabled()
        assert ask.text_content() == "Regrade requested"
        assert_accessible(bea, "a student's regrade request", ".a-regrade")

        p = open_course(browser, server, tmp_path)
        page = p.page
        page.evaluate("(id) => { location.hash = id; }", aid)
        item = page.locator("#regrade li.regrade-req[data-status='open']")
        item.wait_for()
        assert page.text_content("#regrade-count") == "1 open, 1 in all."
        assert item.locator("h3").text_content().startswith(f"Bea B: {GLASS}")
        assert "My ball has kt 0.9" in item.locator(".regrade-reason").text_content()
        item.locator("textarea").fill("Right: a kt of 0.9 is glass.")
        item.locator("input[type=number]").fill("1")
        item.locator("button.regrade-accept").focus()
        page.keyboard.press("Enter")
        page.wait_for_function("() => document.querySelector('#regrade-status').textContent.startsWith('Answered')")
        page.locator("#regrade li.regrade-req[data-status='accepted']").wait_for()
        assert page.text_content("#regrade-count") == "0 open, 1 in all."  # counted again after the answer
        page.locator("#regrade").scroll_into_view_if_needed()
        p.shot("course-regrade-requests")
        assert_accessible(page, "the regrade requests panel", "#regrade")

        with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
            rows = list(csv.reader(io.StringIO(c.get(f"/api/assignments/{aid}/grades.csv").text)))
            assert {r[0]: r[2:4] for r in rows[1:]} == {"bea": ["3", "6"]}

        bea.reload()
        answered = row.locator(".a-regrade-req[data-status='accepted']")
        answered.wait_for()
        assert answered.locator(".a-regrade-reply").text_content() == "Answer: Right: a kt of 0.9 is glass."
        assert row.locator(".a-sub-score").text_content() == "3 / 6"
        assert_accessible(bea, "a student's answered regrade request", ".a-regrade")

        # a better scene (full marks) from her page becomes the grade: its results get the regrade buttons, without
        # a reload; the first submission (no longer the grade) loses its buttons and keeps its answered request
        bea.fill("#a-scene", json.dumps(good_scene()))
        bea.click("#a-submit")
        new = bea.locator(f"#a-sub-list li[data-counts=true]:not([data-id='{sid}'])")
        new.wait_for(timeout=240_000)
        new.locator("button.a-regrade-ask").first.wait_for()
        bea.wait_for_selector(f"#a-sub-list li[data-id='{sid}'][data-counts=false]", state="attached")
        if row.locator(".a-sub-head").get_attribute("aria-expanded") != "true":
            row.locator(".a-sub-head").click()
        row.locator(".a-sub-detail").wait_for()  # drawn as it opens
        row.locator(".a-regrade .a-regrade-req[data-status='accepted']").wait_for()
        assert row.locator("button.a-regrade-ask").count() == 0
        assert "no longer your grade" in row.locator(".a-regrade").text_content()
        assert new.locator(".a-regrade .a-regrade-deadline").text_content().startswith("You can ask until")
        row.locator(".a-regrade").scroll_into_view_if_needed()
        me.shot("assignment-regrade-no-longer-the-grade")
        assert_accessible(bea, "a submission's requests once another is the grade", f"li[data-id='{sid}'] .a-regrade")
    finally:
        me.context.close()
        if p is not None:
            p.context.close()
    assert me.unexpected_errors() == [] and (p is None or p.unexpected_errors() == [])
