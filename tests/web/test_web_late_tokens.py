"""Late tokens in Chromium (server/course/tokens.py, web/js/course/brief.js and latetokens.js): a student sees the
tokens left and what a submission now would spend before submitting, submits, and sees the token spent; the
instructor sees the student's tokens and extensions' history on /course, grants a token, and axe finds no serious
violation in that panel. The server is a subprocess with the real clock (tests/web/conftest.py's): the student's
deadline is an extension to three hours ago (one day's token), nothing waits for a time."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import httpx
import pytest

from tests.support.axe import assert_accessible
from tests.support.course_page import open_course
from tests.support.page import TEACHER
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
CID = "tokens-web"


def spec() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


@pytest.fixture(scope="module")
def hw(server):
    """A course giving 2 tokens, an assignment (deadline tomorrow, no late submissions), a student whose own
    deadline is three hours ago."""
    url = server.url
    r = httpx.post(f"{url}/api/courses", json={"id": CID, "name": "Tokens", "late_tokens": 2}, headers=TEACHER)
    assert r.status_code == 201, r.text
    body = {"spec": spec(), "deadline": (datetime.now(UTC) + timedelta(days=1)).isoformat()}
    r = httpx.post(f"{url}/api/courses/{CID}/assignments", json=body, headers=TEACHER, timeout=60)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    r = httpx.post(f"{url}/api/assignments/{aid}/roster", content="id,name,email\nlou,Lou Late,\n",
                   headers={**TEACHER, "Content-Type": "text/csv"}, timeout=30)  # fmt: skip
    assert r.status_code == 200, r.text
    link = r.json()["students"][0]["link"]
    three_hours_ago = (datetime.now(UTC) - timedelta(hours=3)).isoformat()
    r = httpx.post(f"{url}/api/assignments/{aid}/extensions", headers=TEACHER, timeout=30,
                   json={"student": "lou", "deadline": three_hours_ago, "why": "a move"})  # fmt: skip
    assert r.status_code == 200, r.text
    return {"id": aid, "link": link}


def test_the_student_sees_tokens_left_and_what_a_submission_now_spends(browser, server, hw, desktop):
    page = desktop.page
    page.goto(hw["link"])
    page.wait_for_selector("body[data-ready=true]", state="attached")
    page.wait_for_selector("#a-tokens-row:not([hidden])")
    assert page.text_content("#a-tokens-left") == "2 tokens left in this course"
    assert page.text_content("#a-tokens-now") == "A submission now spends 1 token"
    assert page.get_attribute("#a-time-left", "data-phase") == "tokens"
    assert "spends 1 of your late tokens and is on time" in page.text_content("#a-phase")

    page.fill("#a-scene", (EXAMPLE / "reference.json").read_text())
    page.click("#a-submit")
    page.wait_for_function("() => /Submitted at/.test(document.querySelector('#a-submit-status').textContent)")
    page.wait_for_selector("#a-sub-list .a-tokens")
    assert page.text_content("#a-sub-list .a-tokens") == "1 late token spent: on time"
    page.reload()
    page.wait_for_selector("#a-tokens-row:not([hidden])")
    assert page.text_content("#a-tokens-left") == "1 token left in this course"
    assert page.text_content("#a-tokens-now") == "A submission now spends none."


def test_the_instructor_sees_the_history_and_grants_a_token(browser, server, hw, tmp_path):
    p = open_course(browser, server, tmp_path)
    try:
        page = p.page
        page.goto(f"{server.url}/course#{hw['id']}/lou")
        page.wait_for_selector("#student-detail:not([hidden]) #late-tokens")
        assert "a move" in page.text_content("#ext-history")
        assert page.get_attribute("#tok-left", "data-left") in ("1", "2")  # 1 once the other test submitted
        before = int(page.get_attribute("#tok-left", "data-left"))
        page.fill("#tok-add", "2")
        page.fill("#tok-why", "a doctor's note")
        page.click("#tok-grant")
        page.wait_for_function(f"() => document.querySelector('#tok-left')?.dataset.left === '{before + 2}'")
        assert "granted 2 tokens" in page.text_content("#tok-grants")
        assert "a doctor's note" in page.text_content("#tok-grants")
        assert_accessible(page, "late tokens panel", "#late-tokens")
        assert_accessible(page, "extension history", ".ext-history")
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
