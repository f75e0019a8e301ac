"""Shared fixtures: the renderer's kernels compiled once, and the app in a TestClient for the API tests (built by
tests.support.api.api_client; its helpers live there too); the markers each test gets from what it uses.

tests/ is a package (each folder has an `__init__.py`): test modules import helpers from the `tests.support`
package (`from tests.support.scene import ROOT, scene_dict, small`, `from tests.support.api import Server`); a
folder's own fixtures are in its conftest.py, used without an import."""

from __future__ import annotations

from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent


@pytest.fixture(scope="session")
def compiled_kernels():
    """Compile (or load from cache) the renderer's kernels once per test session."""
    from tracer.rendering.progressive import load_kernels

    load_kernels("cpu")
    return True


# -- the service ----------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def client(tmp_path_factory):
    """The app with one real render worker process, shared by the API tests: the worker starts once.
    Each test leaves no job queued or running behind (it waits for its jobs or cancels them). The app has
    an instructor token (tests.support.api.INSTRUCTOR), and the client is a student with a token of its own:
    its jobs are its own (test_api_owners.py has the other students)."""
    from tests.support.api import INSTRUCTOR, api_client

    with api_client(tmp_path_factory.mktemp("api-data"), workers=1, instructor_token=INSTRUCTOR) as c:
        yield c


@pytest.fixture
def settings(client):
    """The settings of `client`'s app, restored after the test (limits read at submit time can be changed live)."""
    s = client.app.state.settings
    saved = s.model_dump()
    yield s
    for key, value in saved.items():
        setattr(s, key, value)


@pytest.fixture(scope="session")
def client_without_workers(tmp_path_factory):
    """The app with no render worker (submitted jobs wait in the queue), for routes that render nothing;
    a student's client of a server with an instructor token, as `client`."""
    from tests.support.api import INSTRUCTOR, api_client

    with api_client(tmp_path_factory.mktemp("api-data-no-workers"), workers=0, instructor_token=INSTRUCTOR) as c:
        yield c


# -- markers: the tiers of the suite --------------------------------------------------------------
# Registered in pyproject.toml and given here by what a test uses, so that a new test gets them too:
# `./dev test -m "not browser"` is the inner loop's tier (no Chromium), `-m "not slow"` leaves out the tests
# listed in slow_tests.txt (over 10 s each on the 2-core machine, from `--durations`). CI runs everything.

REDIS_WORDS = ("RedisServer", "redis_argv", "tests.support.hosts import")  # redis-server (and network namespaces)
RENDER_WORDS = ("load_kernels", "tracer.rendering", "tracer.radiosity", "tracer.grading", "render_scene")
RENDER_FIXTURES = {"compiled_kernels", "kernels", "client", "settings", "server", "desktop", "phone", "browser"}
_SOURCES: dict[Path, str] = {}


def _source(path: Path) -> str:
    if path not in _SOURCES:
        _SOURCES[path] = path.read_text(errors="replace")
    return _SOURCES[path]


def _slow_tests() -> set[str]:
    listed = TESTS / "slow_tests.txt"
    if not listed.exists():
        return set()
    lines = (line.split("#")[0].strip() for line in listed.read_text().splitlines())
    return {line for line in lines if line}


def pytest_collection_modifyitems(config, items):
    slow = _slow_tests()
    for item in items:
        path = Path(str(item.fspath))
        text = _source(path)
        names = set(getattr(item, "fixturenames", ()))
        if "browser" in names or TESTS / "web" in path.parents:
            item.add_marker(pytest.mark.browser)
        if any(w in text for w in REDIS_WORDS):
            item.add_marker(pytest.mark.redis)
        if names & RENDER_FIXTURES or any(w in text for w in RENDER_WORDS):
            item.add_marker(pytest.mark.render)
        if item.nodeid in slow or item.nodeid.split("[")[0] in slow:
            item.add_marker(pytest.mark.slow)
    # the browser's tests last (a stable sort): Chromium runs once per session (tests/web/conftest.py), and while
    # Playwright's loop is set no other test could asyncio.run(); with xdist's --dist loadfile, once a process
    # takes a browser test file every file left is one too
    items.sort(key=lambda item: item.get_closest_marker("browser") is not None)
