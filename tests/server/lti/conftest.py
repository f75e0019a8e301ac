"""The LTI tests' fixtures, shared by every module here without an import: the service's app served by uvicorn on
loopback (`tool`, one per session, its data directory its own), and a test platform registered with it (`platform`, a
fresh one per test, on its own port, so that no key set or token cached by the tool carries over)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import httpx
import pytest

from server.core.settings import Settings
from server.lti.handler import EchoHandler
from server.lti.tool import LtiTool
from server.main import create_app
from tests.support.api import INSTRUCTOR, bearer
from tests.support.lti_platform import LoopbackServer, Platform


@dataclass
class Tool:
    url: str
    app: object
    client: httpx.Client  # no token; redirects not followed (the tests look at each step)

    @property
    def lti(self) -> LtiTool:
        return self.app.state.lti

    def admin(self) -> dict:
        return bearer(INSTRUCTOR)


@pytest.fixture(scope="session")
def tool(tmp_path_factory) -> Iterator[Tool]:
    data = tmp_path_factory.mktemp("lti-tool") / "data"
    data.mkdir()
    settings = Settings(
        data_dir=data, workers=0, interactive_workers=0, validate_processes=1, previews_ahead=False,
        lessons_ahead=False, answer_again=False, instructor_token=INSTRUCTOR,
    )  # fmt: skip
    app = create_app(settings)
    with LoopbackServer(app) as server, httpx.Client(base_url=server.url, timeout=30) as client:
        # the launch checks alone: the echo page answers a checked launch (what it opens in a course is
        # tests/server/course/test_lms.py's)
        app.state.lti.handler = EchoHandler()
        yield Tool(server.url, app, client)


@pytest.fixture
def platform(tool: Tool) -> Iterator[Platform]:
    """A test platform on loopback, registered with the tool (removed again after the test)."""
    with Platform() as p:
        p.tool_jwks_url = tool.url + "/lti/jwks"
        row = tool.lti.store.register(**p.registration(), now=tool.lti.clock())
        tool.lti.refresh()
        p.registered = row
        try:
            yield p
        finally:
            tool.lti.store.remove(row["id"])
            tool.lti.refresh()
