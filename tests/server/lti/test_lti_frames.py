"""Who may frame which page (server/api/middleware.py's SecurityHeaders with `frame_ancestors`): the registered
platforms' origins may frame the pages an LMS shows, no one else any page, and no one at all without platforms."""

from __future__ import annotations

from fastapi import FastAPI
from fastapi.testclient import TestClient

from server.api.middleware import SecurityHeaders
from server.lti.tool import origin


def client(origins: list[str] | None) -> TestClient:
    app = FastAPI()
    for path in ("/", "/course", "/lti/launch", "/assignments/a1", "/api/jobs", "/courseware"):
        app.get(path)(lambda: {"ok": True})
    app.add_middleware(SecurityHeaders, frame_ancestors=None if origins is None else lambda: origins)
    return TestClient(app)


def test_lti_frames_allowed_to_the_platforms_on_the_lms_pages_only():
    c = client(["https://canvas.instructure.com", "https://sso.canvaslms.com"])
    for path in ("/", "/course", "/lti/launch", "/assignments/a1"):
        r = c.get(path)
        policy = r.headers["content-security-policy"]
        assert "frame-ancestors 'self' https://canvas.instructure.com https://sso.canvaslms.com" in policy, path
        assert "form-action 'self' https://canvas.instructure.com https://sso.canvaslms.com" in policy
        assert "x-frame-options" not in r.headers
        assert r.headers["x-content-type-options"] == "nosniff"
    for path in ("/api/jobs", "/courseware"):
        r = c.get(path)
        assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
        assert r.headers["x-frame-options"] == "DENY"


def test_lti_frames_denied_everywhere_without_platforms():
    for c in (client(None), client([])):
        for path in ("/", "/lti/launch", "/api/jobs"):
            r = c.get(path)
            assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
            assert r.headers["x-frame-options"] == "DENY"


def test_lti_frames_origins_are_plain_web_origins():
    assert origin("https://Canvas.Instructure.com/api/lti/authorize") == "https://canvas.instructure.com"
    assert origin("http://127.0.0.1:8001/auth") == "http://127.0.0.1:8001"
    assert origin("https://[::1]:9000/x") == "https://[::1]:9000"
    assert origin("https://a;b.example/x") is None  # nothing that a policy could read as another directive
    assert origin("https://a b.example/") is None


def test_lti_frames_a_platform_s_service_origin_may_frame_the_tool(tmp_path):
    """A hosted Canvas shows its courses at the school's address, registered as a further service origin."""
    from server.lti.tool import LtiTool

    tool = LtiTool(tmp_path)
    try:
        tool.store.register(
            issuer="https://canvas.instructure.com", client_id="1", auth_url="https://sso.canvaslms.com/auth",
            token_url="https://sso.canvaslms.com/token", jwks_url="https://sso.canvaslms.com/jwks",
            deployment_ids=["d"], service_origins=["https://school.instructure.com"],
        )  # fmt: skip
        assert "https://school.instructure.com" in tool.origins()
    finally:
        tool.close()
