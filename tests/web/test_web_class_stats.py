"""The dashboard's "Class statistics" panel (web/js/course/stats.js, issue #41 item 7) in Chromium: a small
assignment (tests/server/course/test_api_stats.py's) and a class of three whose work is known (ann full marks at
once, bea 2 then 6 points, cid 2 points without the glass), graded by the conftest server's render worker; the
instructor opens /course#<id> and reads the score histogram, each test's pass rate (the glass requirement marked
as failed most), the attempts, each drawn as an SVG with role="img" and a sentence, a caption and its numbers in
a table that opens from the keyboard; axe finds no serious violation in the panel; a screenshot for a person."""

from __future__ import annotations

import httpx
import pytest

from tests.support.api import bearer, wait_for
from tests.support.axe import assert_accessible
from tests.support.course_page import open_course
from tests.support.page import TEACHER
from tests.support.stats import red, reference, small_spec

DEADLINE = "2100-01-01T12:00:00Z"


@pytest.fixture(scope="module")
def assignment(server) -> tuple[str, dict]:
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        r = c.post("/api/assignments", json={"spec": small_spec(), "deadline": DEADLINE})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        roster = "id,name,email\nann,Ann A,\nbea,Bea B,\ncid,Cid C,\ndan,Dan D,\n"
        r = c.post(f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv"})
        assert r.status_code == 200, r.text
        tokens = {s["id"]: bearer(s["token"]) for s in r.json()["students"]}
        sids = []
        for who, scene in [("ann", reference()), ("bea", red(glass=False)), ("cid", red(glass=False)),
                           ("bea", reference())]:  # fmt: skip
            r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=tokens[who])
            assert r.status_code == 202, r.text
            sids.append(r.json()["id"])
        for sid in sids:
            url = f"/api/assignments/{aid}/submissions/{sid}"
            wait_for(lambda u=url: c.get(u).json()["status"] == "graded", 240, f"{sid} graded", 0.2)
    return aid, tokens


def test_web_class_stats_draws_the_histogram_and_pass_rates_with_their_text(browser, server, assignment, tmp_path):
    aid, tokens = assignment
    p = open_course(browser, server, tmp_path)
    try:
        p.page.evaluate("(id) => { location.hash = id; }", aid)
        p.page.wait_for_selector("#stats-rates-svg .rate")
        assert "3 graded students of 4" in p.page.text_content("#stats-status")
        bars = p.page.eval_on_selector_all("#stats-histogram-svg .bar", "gs => gs.map(g => +g.dataset.count)")
        assert bars == [0, 0, 0, 1, 0, 0, 0, 0, 0, 2], bars  # cid's 2 of 6; ann's and bea's 6
        heights = p.page.eval_on_selector_all(
            "#stats-histogram-svg .bar rect", "rs => rs.map(r => +r.getAttribute('height'))"
        )
        assert heights[9] > heights[3] > 0 and heights[0] == 0, heights
        label = p.page.get_attribute("#stats-histogram-svg", "aria-label")
        assert p.page.get_attribute("#stats-histogram-svg", "role") == "img"
        assert "3 graded students out of 6 points" in label and "1 with 1.8 to under 2.4" in label, label
        rates = p.page.eval_on_selector_all(
            "#stats-rates-svg .rate", "gs => gs.map(g => [g.dataset.test, g.dataset.rate])"
        )
        assert [t for t, _ in rates] == ["validity", "a glass object", "an area light", "psnr", "pixels"]
        assert dict(rates)["validity"] == "1"
        assert dict(rates)["a glass object"].startswith("0.666")
        fills = p.page.eval_on_selector_all("#stats-rates-svg .fill", "rs => rs.map(r => +r.getAttribute('width'))")
        assert fills[0] > fills[1] > 0, fills
        worst = p.page.eval_on_selector_all("#stats-rates-svg .worst", "gs => gs.map(g => g.dataset.test)")
        assert worst == ["a glass object"]
        label = p.page.get_attribute("#stats-rates-svg", "aria-label")
        assert "a glass object (requirement) 2 of 3, 67%, failed most" in label, label
        assert "a glass object (1 of 3 fail it)" in p.page.text_content("#stats-summary")
        attempts = p.page.eval_on_selector_all("#stats-attempts-svg .bar", "gs => gs.map(g => +g.dataset.count)")
        assert attempts == [1, 2, 1], attempts  # dan none, ann and cid 1, bea 2
        captions = p.page.eval_on_selector_all(".stats-figure figcaption", "fs => fs.map(f => f.textContent)")
        assert captions[0].startswith("Score distribution") and captions[1].startswith("Pass rate"), captions

        # the numbers behind a picture: a table under a summary, opened from the keyboard
        summary = "#stats-rates details summary"
        p.page.focus(summary)
        p.page.keyboard.press("Enter")
        rows = p.page.eval_on_selector_all(
            "#stats-rates table tbody tr", "trs => trs.map(tr => [...tr.children].map(c => c.textContent))"
        )
        assert rows[1] == ["a glass object (failed most)", "requirement", "2", "3", "67%"], rows
        assert p.page.is_visible("#stats-rates table")
        p.page.click("#stats-histogram details summary")
        p.page.click("#stats-students details summary")
        students = p.page.eval_on_selector_all("#stats-student-table tbody th", "ths => ths.map(t => t.textContent)")
        assert students == ["Ann A (ann)", "Bea B (bea)", "Cid C (cid)", "Dan D (dan)"]
        p.page.locator("#class-stats").scroll_into_view_if_needed()
        p.shot("course-class-stats", full_page=True)
        assert_accessible(p.page, "the class statistics panel", "#class-stats")

        # cid hands in the reference: the status says the class changed (nothing redrawn), Refresh counts it
        with httpx.Client(base_url=server.url, timeout=60) as c:
            r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": reference()}, headers=tokens["cid"])
            assert r.status_code == 202, r.text
            url = f"/api/assignments/{aid}/submissions/{r.json()['id']}"
            wait_for(lambda: c.get(url, headers=tokens["cid"]).json()["status"] == "graded", 240, "cid's graded", 0.2)
        p.page.wait_for_function("() => document.querySelector('#stats-status').textContent.includes('changed since')")
        assert p.page.is_visible("#stats-rates table")  # what the reader had open stays open
        p.page.click("#stats-refresh")
        bars = "[...document.querySelectorAll('#stats-attempts-svg .bar')].map(g => g.dataset.count).join()"
        p.page.wait_for_function(f"() => {bars} === '1,1,2'")  # ann 1, bea 2, cid 2 now, dan none
        assert "changed since" not in p.page.text_content("#stats-status")
        assert p.page.text_content("#stats-summary [data-stat='Requirement failed most']") == "none"  # cid's glass
        p.page.set_viewport_size({"width": 390, "height": 800})  # a phone: nothing wider than the page
        p.page.wait_for_timeout(100)
        wide = p.page.evaluate("() => document.documentElement.scrollWidth - document.documentElement.clientWidth")
        assert wide <= 0, wide
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
