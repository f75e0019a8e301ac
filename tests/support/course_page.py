"""The course page opened as an instructor in Chromium (tests/web/test_web_course_instructor.py and the course's other
page tests)."""

from __future__ import annotations

import json
from pathlib import Path

from tests.support.api import INSTRUCTOR
from tests.support.page import DESKTOP, Page

ZONE = "America/New_York"  # the browser's zone: UTC-05:00 in December, so the deadline's offset is seen


class CoursePage(Page):
    """test_web_page's Page (its console watched) in a browser context whose time zone is ZONE."""

    def __init__(self, browser, server, viewport):
        super().__init__(browser, server, viewport, timezone_id=ZONE, accept_downloads=True)


def write(tmp: Path, name: str, data) -> str:
    path = tmp / name
    path.write_text(data if isinstance(data, str) else json.dumps(data, indent=2))
    return str(path)


def open_course(browser, server, tmp: Path, token: str = INSTRUCTOR):
    """/course with `token` typed in (the admin's, or a staff member's)."""
    p = CoursePage(browser, server, DESKTOP)
    p.allow.append(r"status of 401")  # the page's first request, before the token is typed, is refused
    p.page.goto(f"{server.url}/course")
    p.page.wait_for_selector("body[data-ready=true]", state="attached")
    p.page.fill("#course-token", token)
    p.page.dispatch_event("#course-token", "change")
    p.page.wait_for_function("() => document.querySelector('#course-access-status').dataset.kind === 'ok'")
    return p
