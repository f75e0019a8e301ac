"""The course page's "Audit trail" panel (web/js/course/audit.js, issue #41 item 5) in Chromium: an assignment, a
roster of two, an extension with a reason and a new link made through the API; the instructor opens /course and
reads them in the panel's table (newest first, who, what, before and after, why), filters it by a student and by
the assignment from the keyboard, downloads audit.csv; axe finds no serious violation in the
panel. No render is needed: the module's server has no render worker."""

from __future__ import annotations

import csv
import io
import json

import httpx
import pytest

from tests.support.api import INSTRUCTOR, Server, bearer
from tests.support.axe import assert_accessible
from tests.support.course_page import open_course
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
TEACHER = bearer(INSTRUCTOR)
OUT_OF_PANEL = """() => {
    const html = document.documentElement, box = document.querySelector('#audit').getBoundingClientRect();
    const out = html.scrollWidth > html.clientWidth + 1 ? [`the page scrolls sideways: ${html.scrollWidth}`] : [];
    for (const el of document.querySelectorAll('#audit *')) {
        const r = el.getBoundingClientRect();
        if (r.width && (r.right > box.right + 1 || r.left < box.left - 1)) out.push(`${el.tagName} ${r.right}`);
    }
    return out;
}"""


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("audit-web"), workers=0, env={"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}) as s:
        yield s


@pytest.fixture(scope="module")
def assignment(server) -> str:
    spec = json.loads((EXAMPLE / "assignment.json").read_text())
    spec["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        r = c.post("/api/assignments", json={"spec": spec, "deadline": "2100-01-01T12:00:00Z"})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        roster = "id,name,email\nann,Ann A,\nbea,Bea B,\n"
        r = c.post(f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv"})
        assert r.status_code == 200, r.text
        body = {"student": "ann", "deadline": "2100-01-03T12:00:00Z", "why": "a doctor's note"}
        assert c.post(f"/api/assignments/{aid}/extensions", json=body).status_code == 200
        assert c.post(f"/api/assignments/{aid}/students/bea/link").status_code == 200
    return aid


def test_web_course_audit_panel_lists_filters_pages_and_exports(browser, server, assignment, tmp_path):
    aid = assignment
    p = open_course(browser, server, tmp_path)
    page = p.page
    try:
        page.wait_for_selector("#audit-table tbody tr")
        actions = page.eval_on_selector_all("#audit-table tbody tr", "rs => rs.map(r => r.dataset.action)")
        assert actions == ["link.renew", "extension", "student.add", "student.add", "publish"], actions
        first = page.eval_on_selector_all("#audit-table tbody tr:nth-child(2) td", "ts => ts.map(t => t.innerText)")
        assert first[1:3] == ["admin", "extension"] and first[3].endswith(", student ann"), first
        assert first[4] == "deadline: none"
        assert first[5].startswith("deadline: 2100-01-03")
        assert first[6] == "a doctor's note"
        assert page.text_content("#audit-status") == "5 changes shown."
        assert_accessible(page, "course audit trail", "#audit")

        # the keyboard: the student's field, typed, Enter
        page.focus("#audit-student")
        page.keyboard.type("ann")
        page.keyboard.press("Enter")
        page.wait_for_function("() => document.querySelector('#audit-status').textContent === '2 changes shown.'")
        actions = page.eval_on_selector_all("#audit-table tbody tr", "rs => rs.map(r => r.dataset.action)")
        assert actions == ["extension", "student.add"]
        with page.expect_download() as got:
            page.click("#audit-csv")
        rows = list(csv.DictReader(io.StringIO(open(got.value.path(), encoding="utf-8").read())))
        assert [(r["action"], r["student"]) for r in rows] == [("extension", "ann"), ("student.add", "ann")]

        page.fill("#audit-student", "")
        page.select_option("#audit-assignment", aid)
        page.click("#audit-apply")
        page.wait_for_function("() => document.querySelector('#audit-status').textContent === '4 changes shown.'")
        actions = page.eval_on_selector_all("#audit-table tbody tr", "rs => rs.map(r => r.dataset.action)")
        assert actions == ["extension", "student.add", "student.add", "publish"]  # a new link is the course's
        assert page.is_hidden("#audit-more")  # all on one page
        p.shot("course-audit", full_page=True)
        # a phone's width: each change a block of labelled lines, nothing out of the panel, no sideways scroll
        page.set_viewport_size({"width": 390, "height": 844})
        assert page.evaluate(OUT_OF_PANEL) == []
        assert page.evaluate("() => getComputedStyle(document.querySelector('#audit-table td')).display") == "block"
        p.shot("course-audit-390", full_page=True)
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
