"""The operator's status page in Chromium (/status, web/status.html and web/js/status.js; docs/service.md "The
status page"): before the admin's token it says that it needs it; with it, it shows the worker host and its worker,
the queue by lane, a grade that failed to go back to an LMS (a row of a platform that is not registered: the
server's own poster fails it), the last backup's age, the disk against TRACER_MAX_DATA_BYTES, the version and the
schema; axe finds no serious or critical violation, on a desktop and on a phone (where nothing is wider than the
screen). One server of its own (`python -m server`, one render worker)."""

from __future__ import annotations

import time

import pytest

from server.core.backup import backup
from server.core.migrations import LATEST
from server.course.lms_store import LmsStore
from tests.support.api import INSTRUCTOR, Server, wait_for
from tests.support.axe import assert_accessible
from tests.support.page import DESKTOP, PHONE, Page

LIMIT = 40_000_000


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    env = {"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR, "TRACER_MAX_DATA_BYTES": str(LIMIT)}
    with Server(tmp_path_factory.mktemp("web-status") / "data", workers=1, env=env) as s:
        backup(s.data_dir, tmp_path_factory.mktemp("web-status-backups") / "nightly")
        row = {"platform_id": "gone-lms", "lineitem": "http://127.0.0.1:9/lineitems/1", "user_id": "student-7",
               "assignment_id": "a1", "student": "ada", "score_given": 9.0, "score_max": 13.0}  # fmt: skip
        store = LmsStore(s.data_dir)
        store.add_score(row, time.time())
        # the server's poster tries it within a few seconds: the platform is not registered, so it fails
        wait_for(lambda: store.db.execute("SELECT error FROM course_lti_scores").fetchone()[0], 60, "a failed post")
        yield s


def open_status(page: Page) -> None:
    page.page.goto(f"{page.server.url}/status")
    page.page.wait_for_function("() => document.querySelector('#status-said').dataset.kind === 'error'")
    assert "needs the admin's token (TRACER_INSTRUCTOR_TOKEN)" in page.page.text_content("#status-said")
    page.page.fill("#status-token", "a-course-staff-token-or-a-typo")
    page.page.dispatch_event("#status-token", "change")
    page.page.wait_for_function("() => document.querySelector('#status-said').textContent.includes('refused')")
    assert page.page.get_attribute("#status-token", "aria-invalid") == "true"
    page.page.fill("#status-token", INSTRUCTOR)
    page.page.dispatch_event("#status-token", "change")
    page.page.wait_for_selector("#st-release")


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_web_status_shows_what_an_operator_watches(browser, server, viewport):
    p = Page(browser, server, viewport)
    p.allow.append(r"status of 401")  # the page's first request, before the token is typed
    try:
        open_status(p)
        page = p.page
        health = server.client.get("/api/health").json()
        host = health["workers"][0]["host"]
        workers = page.text_content("#st-workers")
        assert "1 worker on 1 host, all alive." in workers
        assert host in workers
        assert "cpu" in workers
        lanes = page.inner_text("#st-queue")
        assert "Nothing waiting." in lanes
        assert "interactive" in lanes
        assert "batch" in lanes
        lms = page.text_content("#st-lms")
        assert "1 grade failed to post and will be tried again." in lms
        assert "the platform is no longer registered" in lms
        assert "gone-lms" in lms
        backup_text = page.text_content("#st-backup")
        assert "Last backup" in backup_text
        assert "nightly" in backup_text
        assert "No backup" not in backup_text
        disk = page.text_content("#st-disk")
        assert "% of the limit used." in disk
        assert "Limit40 MB" in disk
        release = page.text_content("#st-release")
        assert "0.1.0" in release
        assert f"{LATEST} (this release: {LATEST})" in release
        assert "The database's schema is this release's." in release
        assert page.evaluate("() => document.documentElement.scrollWidth <= window.innerWidth"), "wider than the page"
        p.shot(f"status-{viewport['width']}", full_page=True)
        assert_accessible(page, f"the status page at {viewport['width']} px")
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
