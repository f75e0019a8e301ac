"""The dashboard's grading queue (web/js/course/grading.js, issue #41 item 2) in Chromium: the statistics tests'
small assignment with two manual items (creativity: three levels, lighting: two), ann and bea graded by the
conftest server's render worker; the instructor opens /course#<id> and grades both submissions with the
keyboard alone (1-9 toggle a level of the current item, Tab to the comment and on to the next item, n the next,
b the one before), each choice saved at once through the PUT; the grades the server kept are read back, the
release is pressed from the keyboard, grades.csv has the totals; axe finds no serious violation in the panel."""

from __future__ import annotations

import csv
import io

import httpx
import pytest

from tests.support.axe import assert_accessible
from tests.support.course_page import open_course
from tests.support.manual import publish_class
from tests.support.page import TEACHER

DEADLINE = "2100-01-01T12:00:00Z"


@pytest.fixture(scope="module")
def assignment(server) -> tuple[str, dict]:
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        aid, tokens, sids = publish_class(
            c, "/api/assignments", TEACHER, DEADLINE, "id,name,email\nann,Ann A,\nbea,Bea B,\n"
        )
    return aid, sids, tokens


def test_web_grading_queue_grades_two_submissions_with_the_keyboard_alone(browser, server, assignment, tmp_path):
    aid, sids, tokens = assignment
    p = open_course(browser, server, tmp_path)
    page = p.page
    saved = "(t) => document.querySelector('#grading-status').textContent.startsWith(t)"

    def tab_to(selector: str) -> None:
        for _ in range(8):  # bounded: the item's levels, then its comment
            if page.evaluate("(s) => document.activeElement.matches(s)", selector):
                return
            page.keyboard.press("Tab")
        raise AssertionError(f"Tab never reached {selector}")

    try:
        page.evaluate("(id) => { location.hash = id; }", aid)
        page.wait_for_selector("#grading-start")
        page.wait_for_function(
            "() => document.querySelector('#grading-summary').textContent.startsWith('2 submission')"
        )
        page.focus("#grading-start")
        page.keyboard.press("Enter")
        page.wait_for_function("() => document.querySelector('#grading-who')?.textContent === 'Ann A'")
        assert "Autograder: 6 / 6" in page.text_content("#grading-auto")
        page.wait_for_function("() => document.querySelector('#grading-render').src.startsWith('blob:')")
        page.wait_for_function("() => document.querySelector('#grading-reference').src.startsWith('blob:')")
        assert page.evaluate("() => document.activeElement.id") == "grading-0-level-0"

        # ann: creativity's first level, a comment, lighting's first level
        page.keyboard.press("1")
        page.wait_for_function(saved, arg="Saved creativity: 2 points")
        tab_to("#grading-0-comment")
        page.keyboard.type("a nice story")
        tab_to("#grading-1-level-0")  # leaving the comment saves it; Tab goes on to the next item
        page.wait_for_function(saved, arg="Saved creativity: 2 points, with a comment")
        page.keyboard.press("1")
        page.wait_for_function(saved, arg="Saved lighting: 2 points")
        assert page.text_content("#grading-manual").startswith("Manual part: 4 / 5 (every item graded)")
        page.keyboard.press("n")
        page.wait_for_function("() => document.querySelector('#grading-who')?.textContent === 'Bea B'")

        # bea: a story; back to ann (her choices shown), next again is bea, whose lighting is mood
        page.keyboard.press("2")
        page.wait_for_function(saved, arg="Saved creativity: 0.5 points")
        page.keyboard.press("b")
        page.wait_for_function("() => document.querySelector('#grading-who')?.textContent === 'Ann A'")
        assert page.is_checked("#grading-0-level-0")
        assert page.is_checked("#grading-1-level-0")
        assert page.input_value("#grading-0-comment") == "a nice story"
        page.keyboard.press("n")
        page.wait_for_function("() => document.querySelector('#grading-who')?.textContent === 'Bea B'")
        assert page.is_checked("#grading-0-level-1")
        assert not page.is_checked("#grading-0-level-0")
        tab_to("#grading-1-level-0")
        page.keyboard.press("2")
        page.wait_for_function(saved, arg="Saved lighting: 1 points")
        page.locator("#grading").scroll_into_view_if_needed()
        p.shot("course-grading-queue")
        assert_accessible(page, "the grading queue with a submission", "#grading")
        page.keyboard.press("n")
        page.wait_for_selector("#grading-done")

        with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
            for who, levels in (("ann", [["new objects"], ["area light"]]), ("bea", [["a story"], ["mood"]])):
                view = c.get(f"/api/assignments/{aid}/grading/submissions/{sids[who]}").json()
                assert [i["rubric"] for i in view["manual"]["items"]] == levels, view["manual"]
            assert view["manual"]["points"] == 1.5

            def ann_s_submission():  # ann's own page, her submission opened
                me = p.context.new_page()
                me.goto(f"{server.url}/assignments/{aid}#token={tokens['ann']['Authorization'].split()[1]}")
                head = me.locator(f"#a-sub-list li[data-id='{sids['ann']}'] .a-sub-head")
                head.wait_for()
                if head.get_attribute("aria-expanded") != "true":  # the latest may open by itself
                    head.click()
                return me, me.locator(f"#a-sub-list li[data-id='{sids['ann']}']")

            me, row = ann_s_submission()  # before the release: the auto part, and a word that more comes
            row.locator(".a-manual-later").wait_for()
            assert row.locator(".a-sub-score").text_content() == "6 / 6" and row.locator(".a-manual").count() == 0
            me.close()
            page.focus("#grading-release")
            page.keyboard.press("Enter")
            page.wait_for_function(saved, arg="Released")
            rows = list(csv.reader(io.StringIO(c.get(f"/api/assignments/{aid}/grades.csv").text)))
            assert {r[0]: r[2:4] for r in rows[1:]} == {"ann": ["10", "11"], "bea": ["3.5", "11"]}
            me, row = ann_s_submission()  # after it: each item's points and comment, and the total
            row.locator(".a-manual").wait_for()
            assert row.locator(".a-sub-score").text_content() == "10 / 11"
            items = row.locator(".a-manual-item").all_text_contents()
            assert items[0].startswith("creativity2 / 3") and "a nice story" in items[0], items
            assert row.locator(".a-total").text_content().startswith("Total: 10 / 11")
            assert_accessible(me, "a student's released manual grades", ".a-manual")
            me.close()
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
