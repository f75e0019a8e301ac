"""The tool inside an LMS's page, in a real browser (Playwright driving Debian's Chromium): the test platform
(tests/lti_platform.py) serves a course page that frames the tool's login and offers LTI Platform Storage; the
platform's authentication answer posts the signed launch back by itself, as a real platform's does. With the
state's cookie taken away (as a browser that keeps no cookie for a framed site), the login puts the state into
the platform's page, the launch reads it back there before it opens, and the student lands on their assignment
inside the frame, with its "open in a new window" link; a state read back that is not the launch's is refused
with the page that names the check. Screenshots go to $WEB_SHOTS (default /tmp/web_shots)."""

from __future__ import annotations

import json
from pathlib import Path
from urllib.parse import urlencode

import pytest
from playwright.sync_api import Error as PlaywrightError

from tests.support.api import INSTRUCTOR, Server, bearer, wait_for
from tests.support.lti_platform import LEARNER, Platform
from tests.support.page import SHOTS
from tests.support.scene import ROOT

ADMIN = bearer(INSTRUCTOR)
EXAMPLE = ROOT / "scenes" / "grading"


@pytest.fixture(scope="module")
def setup(tmp_path_factory, browser):
    env = {"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    with Server(tmp_path_factory.mktemp("web-lti"), workers=0, env=env) as server, Platform() as p:
        p.tool_jwks_url = server.url + "/lti/jwks"
        c = server.client
        r = c.post("/api/lti/platforms", json={**p.registration(), "deployment_ids": [p.deployment_id]}, headers=ADMIN)
        assert r.status_code == 201, r.text
        assert c.post("/api/courses", json={"id": "r101", "name": "Rendering 101"}, headers=ADMIN).status_code == 201
        r = c.post("/api/courses/r101/lms/contexts", json={"platform": r.json()["id"], "context": "course-1"},
                   headers=ADMIN)  # fmt: skip
        assert r.status_code == 201, r.text
        spec = json.loads((EXAMPLE / "assignment.json").read_text())
        spec["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
        r = c.post("/api/courses/r101/assignments", json={"spec": spec, "deadline": "2100-01-01T00:00:00Z"},
                   headers=ADMIN)  # fmt: skip
        assert r.status_code == 201, r.text
        yield server, p, r.json()["id"]


def course_page(server, p: Platform, tamper: int = 0) -> str:
    login = f"{server.url}/lti/login?" + urlencode({
        "iss": p.issuer, "login_hint": "hint-1", "target_link_uri": server.url + "/lti/launch",
        "client_id": p.client_id, "lti_deployment_id": p.deployment_id, "lti_storage_target": "_parent",
    })  # fmt: skip
    return f"{p.url}/course-page?" + urlencode({"tool": server.url, "login": login, "tamper": tamper, "hold": 1})


def without_cookies(page) -> None:
    """The browser loses the tool's state cookie between the login and the launch (as one that keeps none for
    a framed site): the platform's authentication answer waits (`hold`) while the cookies are cleared."""
    try:
        wait_for(lambda: (f := tool_frame(page)) and "/auth?" in f.url, 60, "the platform's authentication answer")
    except AssertionError as e:
        raise AssertionError(f"{e}; the frame: {where(page)}") from None
    page.context.clear_cookies()
    page.evaluate("window.holdLaunch = false")


def tool_frame(page):
    """The tool's frame (after a moment in which Playwright takes in the browser's events: reading a frame's url
    alone never lets them in)."""
    page.wait_for_timeout(50)
    return next((f for f in page.frames if f.name == "tool"), None)


def shows(page, selector: str) -> bool:
    """Does the tool's frame show `selector` now (False while it is between two pages)?"""
    f = tool_frame(page)
    try:
        return bool(f and f.query_selector(selector))
    except PlaywrightError:  # its page went away under the question (a navigation): not yet
        return False


def where(page) -> str:
    """What the tool's frame shows now (for a failure's message)."""
    f = tool_frame(page)
    try:
        return f"{f.url}: {f.inner_text('body')[:300]!r}" if f else "no frame"
    except Exception as e:  # noqa: BLE001 (a frame in the middle of a navigation)
        return f"{f.url}: ({e})"


def test_web_lti_a_framed_launch_checks_its_state_in_the_platform_s_storage_and_opens_the_assignment(
    setup,
    browser,
):
    server, p, aid = setup
    p.auto_launch = {"sub": "student-7", "roles": [LEARNER], "custom": {"assignment": aid}}
    context = browser.new_context(viewport={"width": 1100, "height": 800})
    page = context.new_page()
    page.set_default_timeout(60_000)
    page.goto(course_page(server, p))
    without_cookies(page)
    try:
        wait_for(lambda: (f := tool_frame(page)) and f"/assignments/{aid}" in f.url, 60, "the assignment in the frame")
    except AssertionError as e:
        raise AssertionError(f"{e}; the frame: {where(page)}") from None
    frame = tool_frame(page)
    frame.wait_for_selector("body[data-ready=true]")
    assert "Opened from your course's LMS" in frame.inner_text("#a-framed")
    assert frame.get_attribute("#a-new-window", "target") == "_blank"
    assert "Ada Lovelace" in frame.inner_text("main")  # the brief, as the launch's student
    log = page.evaluate("window.storageLog")
    assert [x.split(" ")[0] for x in log] == ["lti.put_data", "lti.put_data", "lti.get_data"], log
    assert log[2].startswith("lti.get_data state_")
    assert log[0] == log[2].replace("get", "put")
    page.screenshot(path=str(Path(SHOTS) / "lti-framed-assignment.png"))
    context.close()


def test_web_lti_a_state_the_platform_s_storage_does_not_hold_is_refused(setup, browser):
    server, p, aid = setup
    p.auto_launch = {"sub": "student-8", "roles": [LEARNER], "custom": {"assignment": aid}}
    context = browser.new_context(viewport={"width": 1100, "height": 800})
    page = context.new_page()
    page.set_default_timeout(60_000)
    page.goto(course_page(server, p, tamper=1))
    without_cookies(page)
    wait_for(lambda: shows(page, "main[data-check=state]"), 60, "the refusal")
    frame = tool_frame(page)
    assert "/lti/launch" in frame.url
    assert "state:" in frame.inner_text("#lti-storage-status")
    page.screenshot(path=str(Path(SHOTS) / "lti-framed-refused.png"))
    context.close()
