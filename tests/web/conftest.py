"""The browser tests' fixtures, shared by every module of tests/web/ without an import: Chromium (`browser`),
started once per session; the page's server (`server`, `python -m server` on loopback, one per module, as the
tests of a module build on each other's jobs and lists); a desktop and a phone page on them (`desktop`, `phone`),
a fresh browser context per test, each failing its test on a console error the test did not expect. A module
that needs a server of its own settings defines its own `server`, which its `desktop`/`phone` then use. The
service with a test LMS linked (`tool` and `lms`, one per module) is tests/support/lms.py's, as for the course's tests.
The helpers (Page, render, set_scene, ...) are tests/support/page.py's."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.api import INSTRUCTOR, Server
from tests.support.lms import lms, tool  # noqa: F401  (the fixtures, registered here for the folder)
from tests.support.page import CHROMIUM, CHROMIUM_ARGS, DESKTOP, PHONE, SHOTS, Page


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    # previews every 0.1 s: a render of a second or two shows several passes
    env = {"TRACER_PREVIEW_INTERVAL": "0.1", "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    with Server(tmp_path_factory.mktemp("web-data"), workers=1, env=env) as s:
        yield s


@pytest.fixture(scope="session")
def browser():
    """Chromium, once per session (each test opens a context of its own: no cookies or storage carry over). The
    browser's tests run after all others (tests/conftest.py orders them): while it is open, Playwright's event loop
    is the thread's, and a test of another folder could not asyncio.run()."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        pytest.fail(f"Playwright is not installed ({exc}); `pip install -e .[test]` (or ./dev test) installs it")
    if not Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} is missing: install Debian's chromium package (./dev test does it)")
    SHOTS.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        yield b
        b.close()


@pytest.fixture
def desktop(browser, server):
    p = Page(browser, server, DESKTOP)
    yield p
    p.context.close()
    assert p.unexpected_errors() == []


@pytest.fixture
def phone(browser, server):
    p = Page(browser, server, PHONE)
    yield p
    p.context.close()
    assert p.unexpected_errors() == []
