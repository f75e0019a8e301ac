"""A feedback policy that hides one image test, in a real browser (issue #42, Major 1): the publish form on /course
previews what a student will see until the deadline and after it, and the student's page says what is hidden and
when it appears, with no text pointing at a picture that is not there.

The fixtures of tests/web/conftest.py (`python -m server` on loopback with one render worker and an instructor
token; Debian's Chromium through Playwright; a page that fails on console errors it did not expect). The
assignment is test_feedback_policy's tiny example (32 x 24 pixels) under docs/assignments.md's example policy
(`pixels` shown after the deadline); the student's scene has its light dimmed (every image test missed).
Screenshots go to $WEB_SHOTS (default /tmp/web_shots)."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import httpx

from tests.support.api import wait_for
from tests.support.axe import assert_accessible
from tests.support.course_page import CoursePage, open_course, write
from tests.support.feedback_policy import POLICY, dimmed, spec
from tests.support.page import DESKTOP, SHOTS, TEACHER, bearer


def preview_col(page, moment: str) -> dict:
    return page.evaluate(
        """(m) => { const col = document.querySelector(`#publish .af-preview-col[data-moment='${m}']`);
            return { head: col.querySelector('h4').textContent,
                     pictures: col.querySelector('.af-preview-pictures').textContent,
                     notice: col.querySelector('.a-withheld')?.textContent ?? null,
                     time: col.querySelector('.a-withheld time')?.getAttribute('datetime') ?? null,
                     tests: Object.fromEntries([...col.querySelectorAll('.a-tests li')].map(li =>
                        [li.dataset.test, {status: li.dataset.status,
                                           output: li.querySelector('.grade-output')?.textContent ?? ''}])) }; }""",
        moment,
    )


def published(server) -> list[str]:
    """The ids of the assignments the admin sees."""
    r = httpx.get(f"{server.url}/api/assignments", headers=TEACHER, timeout=30)
    return [a["id"] for a in r.json()["assignments"]]


def test_the_publish_form_previews_the_feedback_now_and_after_the_deadline(browser, server, tmp_path):
    before = published(server)  # the shared server's: other modules' assignments
    p = open_course(browser, server, tmp_path)
    page = p.page
    page.set_input_files("#publish-spec", write(tmp_path, "hw.json", spec()))
    page.wait_for_selector("#publish tr[data-test='pixels'] select")
    page.fill("#publish-deadline", "2099-12-09T17:00")
    page.select_option("#publish tr[data-test='pixels'] select", "after_deadline")
    page.click("#publish button:has-text('Preview what a student sees')")
    page.wait_for_selector("#publish .af-preview-col[data-moment='after_deadline']")

    now, after = preview_col(page, "now"), preview_col(page, "after_deadline")
    assert "Dec" in now["head"]
    assert "2099" in now["head"]  # until the deadline, in the browser's zone
    assert now["tests"]["pixels"]["status"] == "hidden"
    assert now["tests"]["validity"]["status"] == "passed"
    for k in ("flip", "ssim", "psnr"):
        where = next(x for x in now["tests"][k]["output"].split("\n") if x.startswith("Where to look: "))
        assert "error map" not in where and "rejected pixels" not in where, where
    assert now["pictures"] == "Pictures: their render."  # no error map, no rejected pixels, no metrics
    assert "The error map" not in now["pictures"]
    assert "the error map" in now["notice"] and "the rejected pixels" in now["notice"], now["notice"]
    assert "shown after their deadline" in now["notice"]
    assert now["time"] == "2099-12-09T22:00:00Z"  # 17:00 EST
    assert after["notice"] is None
    assert after["tests"]["pixels"]["status"] == "failed"
    assert "the error map, the rejected pixels" in after["pictures"]
    assert "the FLIP error map" in after["tests"]["flip"]["output"]
    page.locator("#publish .af-preview").screenshot(path=str(SHOTS / "course-feedback-preview.png"))
    assert_accessible(page, "publish form with a feedback preview", "#publish")

    # it follows the form: every test shown now, nothing held back
    page.select_option("#publish tr[data-test='pixels'] select", "")
    page.wait_for_function(
        "() => document.querySelector(\"#publish .af-preview-col[data-moment='now'] li[data-test='pixels']\")"
        "?.dataset.status === 'failed'"
    )
    assert preview_col(page, "now")["notice"] is None
    assert published(server) == before  # a preview publishes nothing
    p.context.close()
    assert p.unexpected_errors() == []


def test_the_students_page_says_what_is_hidden_and_when_it_appears(browser, server):
    deadline = (datetime.now(UTC) + timedelta(days=1)).replace(microsecond=0)
    r = httpx.post(f"{server.url}/api/assignments", json={"spec": spec(), "deadline": deadline.isoformat(), **POLICY},
                   headers=TEACHER, timeout=60)  # fmt: skip
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    r = httpx.post(f"{server.url}/api/assignments/{aid}/roster", content="id,name,email\nhid,Student H,h@x.edu\n",
                   headers={**TEACHER, "Content-Type": "text/csv"}, timeout=30)  # fmt: skip
    assert r.status_code == 200, r.text
    [s] = r.json()["students"]
    r = httpx.post(f"{server.url}/api/assignments/{aid}/submissions", json={"scene": json.dumps(dimmed())},
                   headers=bearer(s["token"]), timeout=30)  # fmt: skip
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    url = f"{server.url}/api/assignments/{aid}/submissions/{sid}"
    wait_for(lambda: httpx.get(url, headers=TEACHER, timeout=30).json()["status"] == "graded", 240, "graded", 0.2)

    p = CoursePage(browser, server, DESKTOP)
    page = p.page
    page.goto(s["link"])
    page.wait_for_selector("body[data-ready=true]", state="attached")
    # the brief says it before any feedback
    note = page.text_content("#a-maps-note")
    assert "error map" in note and "shown after your deadline" in note, note
    row = page.locator(f"#a-sub-list li[data-id='{sid}']")
    row.locator(".a-withheld").wait_for()
    notice = row.locator(".a-withheld").text_content()
    assert "the error map" in notice
    assert "the rejected pixels" in notice
    assert "pixels match the reference" in notice
    assert "shown after your deadline" in notice
    assert row.locator(".a-withheld time").get_attribute("datetime") == deadline.isoformat().replace("+00:00", "Z")
    figs = row.locator("figure.a-fig").evaluate_all("fs => fs.map(f => f.dataset.picture)")
    assert figs == ["render.png"]
    outputs = row.locator(".a-tests li .grade-output").evaluate_all("ps => ps.map(p => p.textContent)")
    where = [x for o in outputs for x in o.split("\n") if x.startswith("Where to look: ")]
    assert where and all("error map" not in x and "rejected pixels" not in x for x in where), where
    row.screenshot(path=str(SHOTS / "assignment-withheld.png"))
    assert_accessible(page, "assignment with feedback withheld")
    p.context.close()
    assert p.unexpected_errors() == []
