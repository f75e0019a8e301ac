"""A course's whole grading story (issue #41's "Done when") in Chromium, as a new instructor, two TAs and two
students would live it, on one server (the app served by uvicorn on loopback, its clock a `Clock`: the late
submission comes when the test moves the clock, nothing sleeps):

1. the instructor creates a course giving 2 late tokens, adds two TAs and publishes a scene assignment with two
   staff-graded items on /course (its "Regrade requests until" first refused at its field: before the deadline);
   the roster comes through the API (its tokens are the students');
2. the instructor switches anonymous grading on and assigns the graders evenly from the grading queue's panel
   (the keyboard: Space on each checkbox, Enter on the buttons);
3. ann submits on time; lou, three hours after the deadline, sees on her page what a submission now spends (one
   token) before she submits from it;
4. each TA opens their staff link and grades their share from the queue with the keyboard alone (Tab to the
   queue's button, Enter, 1-9 for the levels, Tab to the comment and on, n), seeing "Student N", not the name;
5. the dashboard shows each total (auto + manual) marked "not released"; the instructor releases (Enter);
6. lou asks for a regrade of "creativity" from her page with the keyboard (Tab to its "Request a regrade",
   Enter, the reason, Tab, Enter); ta-2, who graded her, accepts it from the Regrade requests panel on /course
   with new points and a reply (the keyboard too); lou reloads and reads the answer and her new total, and
   grades.csv and the dashboard follow;
7. ann sees her total on her page; the audit trail on /course lists the grades, the release, the token spent and
   the regrade's request and answer; the class statistics are drawn with the manual part; axe finds no serious
   violation on each panel. Then the Clock passes the regrade deadline: lou's page says requests are closed.
"""

from __future__ import annotations

import json
import re
from datetime import UTC, datetime, timedelta

import httpx
import pytest

from server.core.settings import Settings
from server.main import create_app
from tests.support.api import INSTRUCTOR, Clock, bearer, wait_for
from tests.support.axe import assert_accessible
from tests.support.course_page import CoursePage, open_course, write
from tests.support.lti_platform import LoopbackServer
from tests.support.manual import manual_spec
from tests.support.page import DESKTOP
from tests.support.stats import red, reference

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=1)  # 2026-12-02 12:00 UTC
DEADLINE_NY = "2026-12-02T07:00"  # the same, as the page's datetime-local in New York (UTC-05:00)
REGRADE_UNTIL = T0 + timedelta(days=8)  # 2026-12-09 12:00 UTC: regrade requests are taken until then
REGRADE_UNTIL_NY = "2026-12-09T07:00"
CID = "story-41"
ADMIN = bearer(INSTRUCTOR)
TAS = (("ta-1", "Tia One"), ("ta-2", "Tom Two"))


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """The app on loopback with one render worker, its clock a `Clock` at T0 (the module's one server; it stands
    in for tests/web/conftest.py's `server`, whose clock is the real one)."""
    data = tmp_path_factory.mktemp("story") / "data"
    data.mkdir()
    settings = Settings(data_dir=data, workers=1, interactive_workers=0, validate_processes=1, previews_ahead=False,
                        lessons_ahead=False, answer_again=False, instructor_token=INSTRUCTOR)  # fmt: skip
    app = create_app(settings)
    with LoopbackServer(app) as s:
        app.state.clock = Clock(T0)
        s.app = app
        yield s


def tab_to(page, selector: str, most: int = 400) -> None:
    """Tab (bounded) until `selector` holds the focus: the keyboard's way to a control."""
    for _ in range(most):
        if page.evaluate("(s) => !!document.activeElement?.matches(s)", selector):
            return
        page.keyboard.press("Tab")
    raise AssertionError(f"Tab never reached {selector} in {most} presses")


def open_row(page, row: str) -> None:
    """A student's submission `row` (a selector) shown open: its head pressed by the keyboard when closed."""
    head = f"{row} .a-sub-head"
    page.wait_for_selector(head)
    if page.get_attribute(head, "aria-expanded") != "true":
        page.focus(head)
        page.keyboard.press("Enter")
    page.wait_for_selector(f"{row} .a-regrade")


def status_starts(page, selector: str, text: str) -> None:
    page.wait_for_function("([s, t]) => document.querySelector(s)?.textContent.startsWith(t)", arg=[selector, text])


def test_web_course_story_from_publishing_to_the_released_total(browser, server, tmp_path):
    clock, url = server.app.state.clock, server.url
    api = httpx.Client(base_url=url, timeout=60, headers=ADMIN)
    pages: list[CoursePage] = []
    try:
        # -- 1. the instructor: a course with late tokens, two TAs, the assignment with two manual items
        prof = open_course(browser, server, tmp_path)
        pages.append(prof)
        page = prof.page
        page.fill("#new-course-id", CID)
        page.fill("#new-course-name", "Rendering 241")
        page.fill("#new-course-tokens", "2")
        page.click("#course-form button[type=submit]")
        page.wait_for_selector(f"#course-list li[data-id={CID}]")
        links: dict[str, str] = {}
        for person, name in TAS:
            page.fill("#staff-id", person)
            page.fill("#staff-name", name)
            page.select_option("#staff-role", "ta")
            page.click("#staff-form button[type=submit]")
            before = list(links.values())
            page.wait_for_function(
                "(was) => !!document.querySelector('#staff-link')?.textContent"
                " && !was.includes(document.querySelector('#staff-link').textContent)",
                arg=before,
            )
            links[person] = page.text_content("#staff-link")
        assert len(set(links.values())) == 2, links
        assert page.input_value("#course-into") == CID
        page.set_input_files("#publish-spec", write(tmp_path, "hw.json", manual_spec()))
        page.fill("#publish-deadline", DEADLINE_NY)
        # "Regrade requests until" before the deadline: refused at its field, nothing published; then a good one
        prof.allow.append(r"status of 422")  # the browser logs the refused request
        page.fill("#publish-regrade_deadline", "2026-12-02T06:00")
        page.click("#publish button[type=submit]")
        page.wait_for_selector("#publish-regrade_deadline-err li")
        assert "regrade deadline must not be before the deadline" in page.text_content("#publish-regrade_deadline-err")
        assert page.get_attribute("#publish-regrade_deadline-err li", "data-path") == "regrade_deadline"
        assert page.get_attribute("#publish-regrade_deadline", "aria-invalid") == "true"
        assert page.evaluate("() => document.activeElement.id") == "publish-regrade_deadline"
        assert api.get("/api/assignments").json()["assignments"] == []
        page.fill("#publish-regrade_deadline", REGRADE_UNTIL_NY)
        page.click("#publish button[type=submit]")
        page.wait_for_function("() => /^#[0-9a-f]{32}$/.test(location.hash)")
        aid = page.evaluate("() => location.hash.slice(1)")
        a = api.get(f"/api/assignments/{aid}").json()
        assert a["deadline"] == "2026-12-02T12:00:00Z"
        assert ([m["name"] for m in a["spec"]["manual"]] == [
            "creativity", "lighting"
        ])  # fmt: skip
        assert a["policy"]["regrade_deadline"] == a["regrade_deadline"] == "2026-12-09T12:00:00Z"
        r = api.post(f"/api/assignments/{aid}/roster", content="id,name,email\nann,Ann Early,\nlou,Lou Late,\n",
                     headers={"Content-Type": "text/csv"})  # fmt: skip
        assert r.status_code == 200, r.text
        students = {s["id"]: s for s in r.json()["students"]}

        # -- 2. anonymous grading on, the graders dealt evenly: from the grading panel, by the keyboard
        page.reload()
        page.wait_for_selector("#grading-grader-0")
        page.focus("#grading-anonymous")
        page.keyboard.press("Space")
        wait_for(lambda: api.get(f"/api/assignments/{aid}/grading").json()["anonymous"], 30, "anonymous grading")
        staff = page.eval_on_selector_all("#grading-staff input", "bs => bs.map(b => b.dataset.person)")
        assert staff == ["ta-1", "ta-2"], staff  # the admin is no staff member of the course
        for i in range(2):
            page.focus(f"#grading-grader-{i}")
            page.keyboard.press("Space")
        assert page.text_content("label[for=grading-grader-0]").strip() == "Tia One (ta-1, TA)"
        tab_to(page, "#grading-assign", 10)
        page.keyboard.press("Enter")
        status_starts(page, "#grading-status", "Assigned evenly: ta-1 1, ta-2 1.")
        assert_accessible(page, "the grading panel with its graders", "#grading")

        # -- 3. the students: ann on time (the API), lou three hours late from her page, told first what it spends
        r = httpx.post(f"{url}/api/assignments/{aid}/submissions", json={"scene": reference()},
                       headers=bearer(students["ann"]["token"]), timeout=60)  # fmt: skip
        assert r.status_code == 202, r.text
        sids = {"ann": r.json()["id"]}
        clock.now = DEADLINE + timedelta(hours=3)
        lou = CoursePage(browser, server, DESKTOP)
        pages.append(lou)
        lou.page.goto(students["lou"]["link"])
        lou.page.wait_for_selector("#a-tokens-row:not([hidden])")
        assert lou.page.text_content("#a-tokens-left") == "2 tokens left in this course"
        assert lou.page.text_content("#a-tokens-now") == "A submission now spends 1 token"
        lou.page.fill("#a-scene", json.dumps(red(glass=False)))
        lou.page.click("#a-submit")
        lou.page.wait_for_selector("#a-sub-list .a-tokens")
        assert lou.page.text_content("#a-sub-list .a-tokens") == "1 late token spent: on time"
        sids["lou"] = lou.page.get_attribute("#a-sub-list li[data-id]", "data-id")
        for sid in sids.values():
            u = f"/api/assignments/{aid}/submissions/{sid}"
            wait_for(lambda u=u: api.get(u).json()["status"] == "graded", 240, f"{sid} graded", 0.2)

        # -- 4. each TA grades their share from the queue, with the keyboard alone, names hidden
        clock.now = DEADLINE + timedelta(hours=5)
        tas: dict[str, CoursePage] = {}
        shares = {"ta-1": ("Student 1", ["1", "2"], "a story and new objects"), "ta-2": ("Student 2", ["2"], "")}
        for person, (label, creativity, comment) in shares.items():
            ta = tas[person] = CoursePage(browser, server, DESKTOP)
            pages.append(ta)
            tp = ta.page
            tp.goto(links[person])
            tp.wait_for_selector("#course-role")
            tp.goto(f"{url}/course#{aid}")
            tp.wait_for_selector("#grading-start")
            status_starts(tp, "#grading-summary", "1 submission(s) to grade in your queue")
            assert tp.locator("#grading-graders").count() == 0  # a TA assigns no graders
            tp.evaluate("() => document.activeElement?.blur()")
            tab_to(tp, "#grading-start")
            tp.keyboard.press("Enter")
            tp.wait_for_function("(l) => document.querySelector('#grading-who')?.textContent === l", arg=label)
            assert tp.evaluate("() => document.activeElement.id") == "grading-0-level-0"
            for key in creativity:
                tp.keyboard.press(key)
                status_starts(tp, "#grading-status", "Saved creativity")
            if comment:
                tab_to(tp, "#grading-0-comment", 8)
                tp.keyboard.type(comment)
            tab_to(tp, "#grading-1-level-0", 8)  # leaving the comment saves it
            tp.keyboard.press("2")  # lighting: mood
            status_starts(tp, "#grading-status", "Saved lighting: 1 points")
            assert tp.text_content("#grading-manual").startswith("Manual part:")
            assert_accessible(tp, "a TA's grading queue", "#grading")
            tp.keyboard.press("n")
            tp.wait_for_selector("#grading-done")
            tp.wait_for_function("() => document.querySelectorAll('#roster-rows tr[data-student]').length === 2")
            names = tp.eval_on_selector_all("#roster-rows tr[data-student] .sname", "ns => ns.map(n => n.textContent)")
            assert names == ["Student 1", "Student 2"], names  # the dashboard too: labels until the release
        grades = {s: api.get(f"/api/assignments/{aid}/grading/submissions/{sids[s]}").json()["manual"] for s in sids}
        assert (grades["ann"]["points"], grades["lou"]["points"]) == (3.5, 1.5)  # 2.5 + 1 (clamped 3), 0.5 + 1
        assert grades["ann"]["items"][0]["comment"] == "a story and new objects"

        # -- 5. the dashboard's totals, not released yet; the release from the keyboard
        page.reload()
        page.wait_for_selector("#roster-rows tr[data-student=lou] .badge.not-released")
        totals = page.eval_on_selector_all("#roster-rows tr[data-student] td.score", "ts => ts.map(t => t.innerText)")
        assert [re.sub(r"\s", "", t) for t in totals] == ["9.5/11notreleased", "3.5/11notreleased"], totals
        assert_accessible(page, "the dashboard's roster with totals", ".board-roster")
        page.focus("#grading-release")
        page.keyboard.press("Enter")
        status_starts(page, "#grading-status", "Released")
        page.reload()
        page.wait_for_selector("#roster-rows tr[data-student=ann] td.score strong")
        assert page.locator("#roster-rows .badge.not-released").count() == 0
        rows = api.get(f"/api/assignments/{aid}/grades.csv").text.splitlines()[1:]
        assert [r.split(",")[2:4] for r in rows] == [["9.5", "11"], ["3.5", "11"]]

        # -- 6. lou asks for a regrade of "creativity" from her page by the keyboard; ta-2, who graded her,
        #       accepts it from the Regrade requests panel with new points and a reply; lou reads the answer
        clock.now = DEADLINE + timedelta(hours=6)
        lp = lou.page
        lp.reload()
        mine = f"#a-sub-list li[data-id='{sids['lou']}']"
        open_row(lp, mine)
        lp.wait_for_selector(f"{mine} li.a-manual-item[data-item=creativity] .pts")
        assert lp.text_content(f"{mine} li.a-manual-item[data-item=creativity] .pts") == "0.5 / 3"
        status_starts(lp, f"{mine} .a-regrade-deadline", "You can ask until")  # the requests' list has come
        ask = f"{mine} button.a-regrade-ask[data-item=creativity]"
        lp.focus(f"{mine} .a-sub-head")
        tab_to(lp, ask, 80)
        assert lp.get_attribute(ask, "aria-label") == "Request a regrade of creativity"
        lp.keyboard.press("Enter")
        lp.wait_for_function("() => document.activeElement?.matches('form.a-regrade-form textarea')")
        lp.keyboard.type("I added a story: the red sky is sunset over the sea, not just new objects.")
        lp.keyboard.press("Tab")  # to Send
        lp.keyboard.press("Enter")
        status_starts(lp, f"{mine} .a-regrade-status", "Sent: your request about “creativity”")
        lp.wait_for_selector(f"{mine} .a-regrade-req[data-status=open][data-item=creativity]")
        assert lp.is_disabled(ask)
        assert lp.text_content(ask) == "Regrade requested"
        assert_accessible(lp, "lou's regrade request", f"{mine} .a-regrade")

        clock.now = DEADLINE + timedelta(hours=7)
        tp = tas["ta-2"].page
        tp.reload()
        req = "#regrade li.regrade-req[data-status=open]"
        tp.wait_for_selector(req)
        assert tp.locator("#regrade li.regrade-req").count() == 1
        assert tp.text_content(f"{req} h3").startswith("Lou Late: creativity")  # released: names shown
        assert "the red sky is sunset" in tp.text_content(f"{req} .regrade-reason")
        assert "points now 0.5 / 3" in tp.text_content(f"{req} .hint")
        tp.focus("#regrade-filter")
        tab_to(tp, "#regrade-0-reply", 6)
        tp.keyboard.type("Yes: a story and new objects, 2 points.")
        tp.keyboard.press("Tab")  # to the new points
        tp.keyboard.type("2")
        tp.keyboard.press("Tab")  # to Accept
        tp.keyboard.press("Enter")
        status_starts(tp, "#regrade-status", "Answered: Lou Late's request about creativity accepted.")
        tp.wait_for_selector("#regrade li.regrade-req[data-status=accepted]")
        assert "points now 2 / 3" in tp.text_content("#regrade li.regrade-req .hint")
        assert_accessible(tp, "the regrade requests panel, answered", "#regrade")

        lp.reload()
        open_row(lp, mine)
        answer = f"{mine} .a-regrade-req[data-status=accepted]"
        lp.wait_for_selector(answer)
        assert lp.text_content(f"{answer} .a-regrade-reply") == "Answer: Yes: a story and new objects, 2 points."
        assert "Points now: 2 / 3" in lp.text_content(answer)
        assert lp.text_content(f"{mine} li.a-manual-item[data-item=creativity] .pts") == "2 / 3"
        assert lp.text_content(f"{mine} .a-total").startswith("Total: 5 / 11")  # 2 + (2 + 1)
        assert lp.text_content(f"{mine} .a-sub-score") == "5 / 11"
        assert lp.text_content(ask) == "Request a regrade"
        assert not lp.is_disabled(ask)  # answered: may ask again
        assert_accessible(lp, "lou's answered regrade request", f"{mine} .a-regrade")
        rows = api.get(f"/api/assignments/{aid}/grades.csv").text.splitlines()[1:]
        assert [r.split(",")[2:4] for r in rows] == [["9.5", "11"], ["5", "11"]]
        page.reload()
        page.wait_for_function(
            "() => document.querySelector('#roster-rows tr[data-student=lou] td.score')?.innerText.startsWith('5')"
        )

        # -- 7. ann's total on her page; the statistics drawn; the audit trail on /course
        me = CoursePage(browser, server, DESKTOP)
        pages.append(me)
        me.page.goto(students["ann"]["link"])
        row = me.page.locator(f"#a-sub-list li[data-id='{sids['ann']}']")
        row.locator(".a-sub-head").wait_for()
        if row.locator(".a-sub-head").get_attribute("aria-expanded") != "true":
            row.locator(".a-sub-head").click()
        row.locator(".a-total").wait_for()
        assert row.locator(".a-total").text_content().startswith("Total: 9.5 / 11")

        page.wait_for_selector("#stats-histogram-svg .bar", state="attached")
        bars = page.eval_on_selector_all("#stats-histogram-svg .bar", "gs => gs.map(g => +g.dataset.count)")
        assert bars == [0, 0, 0, 0, 1, 0, 0, 0, 1, 0], bars  # 5 (lou's, regraded) and 9.5 of 11
        assert "out of 11 points" in page.get_attribute("#stats-histogram-svg", "aria-label")
        assert_accessible(page, "the class statistics", "#class-stats")

        page.goto(f"{url}/course")
        page.wait_for_selector("#audit-course")
        page.select_option("#audit-course", CID)
        page.select_option("#audit-assignment", aid)
        page.click("#audit-apply")
        page.wait_for_function("() => /changes shown/.test(document.querySelector('#audit-status').textContent)")
        actions = page.eval_on_selector_all("#audit-table tbody tr", "rs => rs.map(r => r.dataset.action)")
        # newest first: the regrade's answer (with its override of lou's manual grade), its request, the release
        assert actions.index("regrade.answer") < actions.index("regrade.request") < actions.index("assignment.release")
        assert actions.count("manual.grade") == 7, actions  # 3 + 3 from the queue, 1 the accepted regrade's
        asked = page.locator("#audit-table tbody tr[data-action='regrade.request'] td").all_inner_texts()
        answered = page.locator("#audit-table tbody tr[data-action='regrade.answer'] td").all_inner_texts()
        assert asked[1:3] == ["student:lou", "regrade.request"] and "item: creativity" in asked[5], asked
        assert answered[1:3] == ["ta:ta-2", "regrade.answer"], answered
        assert "item_points: 0.5" in answered[4] and "status: accepted" in answered[5], answered
        assert "item_points: 2" in answered[5] and answered[6] == "Yes: a story and new objects, 2 points.", answered
        assert {"tokens.spend", "manual.graders", "manual.anonymous", "publish"} <= set(actions), actions
        assert actions.count("tokens.spend") == 1, actions  # once: the check before the file is written records none
        spend = page.locator("#audit-table tbody tr[data-action='tokens.spend'] td").all_inner_texts()
        assert spend[1] == "student:lou" and "tokens_left: 2" in spend[4] and "tokens_left: 1" in spend[5], spend
        assert_accessible(page, "the audit trail of the story", "#audit")

        # -- the regrade deadline past (the Clock): lou's page says requests are closed, her answer stays
        clock.now = REGRADE_UNTIL + timedelta(minutes=1)
        lp.reload()
        open_row(lp, mine)
        status_starts(lp, f"{mine} .a-regrade-deadline", "Requests were taken until")
        lp.wait_for_selector(answer)
        assert lp.locator(f"{mine} button.a-regrade-ask").count() == 7  # each test and manual item: all hidden
        assert lp.locator(f"{mine} button.a-regrade-ask:visible").count() == 0
        late = {"item": "lighting", "reason": "too late"}
        r = httpx.post(f"{url}/api/assignments/{aid}/submissions/{sids['lou']}/regrade-requests", json=late,
                       headers=bearer(students["lou"]["token"]), timeout=60)  # fmt: skip
        assert r.status_code == 403 and r.json()["errors"][0]["path"] == "regrade_deadline", r.text
        ann = f"#a-sub-list li[data-id='{sids['ann']}']"  # ann asked nothing: no button is promised her
        me.page.reload()
        open_row(me.page, ann)
        status_starts(me.page, f"{ann} .a-regrade-deadline", "Requests were taken until")
        assert me.page.text_content(f"{ann} .a-regrade-list") == "None: the regrade deadline has passed."
        assert me.page.locator(f"{ann} button.a-regrade-ask:visible").count() == 0
    finally:
        api.close()
        for p in pages:
            p.context.close()
    assert [e for p in pages for e in p.unexpected_errors()] == []
