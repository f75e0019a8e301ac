"""The browser tests' fixtures, shared by every module of tests/web/ without an import: Chromium (`browser`), started
once per session; the page's server (`server`, `python -m server` on loopback with one render worker), also once per
session (one per xdist process), shared by the modules that do not define their own, each of which leaves its queue
idle (`shared_server_left_idle`); a desktop and a phone page on them (`desktop`, `phone`), a browser context and
page lent per test (tests/support/page.py: given back cleaned, so no cookies, storage, listeners or routes carry
over), each failing its test on a console error the test did not expect. A module on the shared server asserts only
about what it made itself (its jobs, assignments, courses and students, by their ids), never about the server's
totals; a module that needs a fresh server, or a server of its own settings, defines its own `server`, which its
`desktop`/`phone` then use. The service with a test LMS linked (`tool` and `lms`, one per module) is
tests/support/lms.py's, as for the course's tests. The helpers (Page, render, set_scene, ...) are
tests/support/page.py's."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.support.api import INSTRUCTOR, Server, bearer, run_solutions
from tests.support.lms import lms, tool  # noqa: F401  (the fixtures, registered here for the folder)
from tests.support.page import CHROMIUM, CHROMIUM_ARGS, DESKTOP, PHONE, SHOTS, Page

POLL_MS = 40  # how often a page's wait_for_function looks again, unless a test says (see below)

# Playwright's wait_for_function polls on every animation frame by default: a frame forced 60 times a second for the
# whole wait, 9 % of a core in the renderer while a test waits (0.6 % at 100 ms; measured on the lessons' page). The
# suite waits that way in about 180 places, so every page's (and frame's) default is a poll each POLL_MS instead: a
# condition met is seen at most POLL_MS later. test_web_lessons and test_web_page: 167-184 s of CPU with frames, 150
# s with the poll (BENCHMARKS.md, session 48).


def _poll_by_default() -> None:
    try:
        from playwright.sync_api import Frame, Page
    except ImportError:  # the browser fixture fails each test with the reason
        return
    for cls in (Page, Frame):

        def polled(self, expression, *, arg=None, polling=None, timeout=None, _wait=cls.wait_for_function):
            return _wait(self, expression, arg=arg, polling=POLL_MS if polling is None else polling, timeout=timeout)

        cls.wait_for_function = polled


_poll_by_default()

SHARED: list[Server] = []  # the session's shared server, once started (in this process)
IDLE_TIMEOUT = 120  # s: the work a module left queued or running (a grading's last renders) to end


@pytest.fixture(scope="session")
def server(tmp_path_factory):
    """The page's server, started once per session (each of a render worker's starts costs seconds of CPU)."""
    # previews every 0.1 s: a render of a second or two shows several passes
    env = {"TRACER_PREVIEW_INTERVAL": "0.1", "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    # every page of the session is a new student on 127.0.0.1, within the caps' hour: the whole session's tokens
    # and joins would pass one address's caps (60 and 20), which tests/server/core/test_api_clients.py tests
    env |= {"TRACER_MAX_NEW_TOKENS_PER_ADDRESS": "100000", "TRACER_MAX_JOINS_PER_ADDRESS": "100000"}
    env |= run_solutions(tmp_path_factory)  # the examples' radiosity previews solved once in a run
    with Server(tmp_path_factory.mktemp("web-data"), workers=1, env=env) as s:
        SHARED.append(s)
        yield s
        SHARED.remove(s)


def busy_lanes(s: Server) -> dict[str, dict[str, int]]:
    """The lanes of `s`'s queue that hold a queued or running job (GET /api/status, the admin's)."""
    lanes = s.client.get("/api/status", headers=bearer(INSTRUCTOR)).raise_for_status().json()["queue"]
    return {lane: n for lane, n in lanes.items() if n["queued"] or n["running"]}


@pytest.fixture(scope="module", autouse=True)
def shared_server_left_idle():
    """After each module, the shared server's queue is idle again (as a fresh server's is), so the next module's
    tests find its only worker free: a queued job's place in line, a long job that must start at once."""
    yield
    for s in SHARED:
        deadline = time.monotonic() + IDLE_TIMEOUT
        while left := busy_lanes(s):
            assert time.monotonic() < deadline, f"the module left work queued past {IDLE_TIMEOUT} s: {left}"
            time.sleep(0.2)


@pytest.fixture(scope="session")
def browser():
    """Chromium, once per session (each test is lent a context and page of its own, given back cleaned: no cookies or
    storage carry over). The browser's tests run after all others (tests/conftest.py orders them): while it is open,
    Playwright's event loop is the thread's, and a test of another folder could not asyncio.run()."""
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
