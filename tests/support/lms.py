"""A course in a test LMS: the service on loopback (one render worker, its clock a `Clock`) and a test platform
(tests/support/lti_platform.py) registered with it, its course-1 linked to course gfx with an assignment published
there. The fixtures `tool` and `lms` (one per module) are registered for tests/server/course/ and tests/web/ by their
conftest.py; tests/server/course/test_lms.py and tests/web/test_web_course_lms.py use them."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import httpx
import pytest

from server.core.settings import Settings
from server.main import create_app
from tests.support.api import INSTRUCTOR, Clock, bearer
from tests.support.lti_platform import LoopbackServer, Platform
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
ADMIN = bearer(INSTRUCTOR)
NRPS = "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice"


@pytest.fixture(scope="module")
def tool(tmp_path_factory):
    data = tmp_path_factory.mktemp("lms") / "data"
    data.mkdir()
    settings = Settings(data_dir=data, workers=1, interactive_workers=0, validate_processes=1, previews_ahead=False,
                        lessons_ahead=False, answer_again=False, instructor_token=INSTRUCTOR)  # fmt: skip
    app = create_app(settings)
    with LoopbackServer(app) as server, httpx.Client(base_url=server.url, timeout=60) as client:
        app.state.clock = Clock(T0)
        yield server.url, app, client


@pytest.fixture(scope="module")
def lms(tool):
    """The platform registered, its course-1 linked to course gfx, and an assignment published in gfx."""
    url, app, client = tool
    with Platform() as p:
        p.tool_jwks_url = url + "/lti/jwks"
        r = client.post("/api/lti/platforms", json={**p.registration(), "deployment_ids": [p.deployment_id]},
                        headers=ADMIN)  # fmt: skip
        assert r.status_code == 201, r.text
        pid = p.registered_id = r.json()["id"]
        assert client.post("/api/courses", json={"id": "gfx", "name": "Graphics"}, headers=ADMIN).status_code == 201
        r = client.post("/api/courses/gfx/lms/contexts", json={"platform": pid, "context": "course-1"}, headers=ADMIN)
        assert r.status_code == 201, r.text
        spec = json.loads((EXAMPLE / "assignment.json").read_text())
        spec["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
        body = {"spec": spec, "deadline": (T0 + timedelta(days=2)).isoformat()}
        r = client.post("/api/courses/gfx/assignments", json=body, headers=ADMIN)
        assert r.status_code == 201, r.text
        yield p, r.json()["id"]
