"""python -m server.lti (register, list, remove, show-tool) and the admin's API of platforms."""

from __future__ import annotations

import json
import subprocess
import sys

from server.lti.command import CANVAS_HEADER, main
from tests.support.api import bearer, student_token
from tests.support.scene import ROOT

PLATFORM = [
    "--issuer", "https://moodle.example.edu", "--client-id", "abc123",
    "--auth-url", "https://moodle.example.edu/mod/lti/auth.php",
    "--token-url", "https://moodle.example.edu/mod/lti/token.php",
    "--jwks-url", "https://moodle.example.edu/mod/lti/certs.php",
]  # fmt: skip


def test_lti_command_register_list_remove(tmp_path, capsys):
    data = ["--data-dir", str(tmp_path)]
    assert main(["register", *PLATFORM, "--deployment", "1", "--deployment", "2", "--name", "Moodle", *data]) == 0
    pid, line = capsys.readouterr().out.splitlines()
    assert len(pid) == 12
    assert "https://moodle.example.edu (Moodle)" in line
    assert "deployments: 1, 2" in line
    assert main(["list", *data]) == 0
    assert capsys.readouterr().out.startswith(pid + "  https://moodle.example.edu")
    assert main(["remove", pid, *data]) == 0 and main(["remove", pid, *data]) == 1
    assert main(["list", *data]) == 0 and capsys.readouterr().out.splitlines()[-1] == f"removed {pid}"


def test_lti_command_register_names_a_bad_field(tmp_path, capsys):
    argv = ["register", *PLATFORM, "--deployment", "1", "--data-dir", str(tmp_path)]
    argv[argv.index("--token-url") + 1] = "http://moodle.example.edu/mod/lti/token.php"
    assert main(argv) == 1
    assert capsys.readouterr().err.startswith("token_url: expected an https:// URL")


def test_lti_command_show_tool_prints_canvas_json():
    r = subprocess.run([sys.executable, "-m", "server.lti", "show-tool", "--base", "https://tool.example.edu/"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 0, r.stderr
    text, _, canvas = r.stdout.partition(CANVAS_HEADER)
    assert "https://tool.example.edu/lti/login" in text
    assert "https://tool.example.edu/lti/jwks" in text
    key = json.loads(canvas)
    assert key["oidc_initiation_url"] == "https://tool.example.edu/lti/login"
    assert key["target_link_uri"] == "https://tool.example.edu/lti/launch"
    assert key["public_jwk_url"] == "https://tool.example.edu/lti/jwks"
    assert "https://purl.imsglobal.org/spec/lti-ags/scope/score" in key["scopes"]
    assert "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly" in key["scopes"]
    (ext,) = key["extensions"]
    assert ext["privacy_level"] == "public"
    assert ext["domain"] == "tool.example.edu"
    kinds = {p["placement"]: p["message_type"] for p in ext["settings"]["placements"]}
    assert kinds == {"course_navigation": "LtiResourceLinkRequest", "assignment_selection": "LtiDeepLinkingRequest",
                     "link_selection": "LtiDeepLinkingRequest"}  # fmt: skip


def test_lti_api_platforms_are_the_admins(tool):
    body = {"issuer": "https://canvas.instructure.com", "client_id": "10000000000042", "deployment_ids": ["7:x"],
            "auth_url": "https://sso.canvaslms.com/api/lti/authorize_redirect",
            "token_url": "https://sso.canvaslms.com/login/oauth2/token",
            "jwks_url": "https://sso.canvaslms.com/api/lti/security/jwks", "name": "Canvas"}  # fmt: skip
    assert tool.client.post("/api/lti/platforms", json=body).status_code == 401
    assert tool.client.post("/api/lti/platforms", json=body, headers=bearer(student_token())).status_code == 401
    r = tool.client.post("/api/lti/platforms", json=body, headers=tool.admin())
    assert r.status_code == 201, r.text
    pid = r.json()["id"]
    assert r.json()["deployment_ids"] == ["7:x"]
    listed = tool.client.get("/api/lti/platforms", headers=tool.admin()).json()
    assert pid in [p["id"] for p in listed]
    page = tool.client.get("/course")  # the platform's origins may frame the course's pages at once
    assert "https://canvas.instructure.com https://sso.canvaslms.com" in page.headers["content-security-policy"]
    assert tool.client.delete(f"/api/lti/platforms/{pid}", headers=tool.admin()).status_code == 204
    assert tool.client.delete(f"/api/lti/platforms/{pid}", headers=tool.admin()).status_code == 404
    page = tool.client.get("/course")
    assert "canvas" not in page.headers["content-security-policy"]


def test_lti_api_register_names_a_bad_field(tool):
    body = {"issuer": "https://lms.example.edu", "client_id": "c", "auth_url": "http://lms.example.edu/auth",
            "token_url": "https://lms.example.edu/token", "jwks_url": "https://lms.example.edu/jwks"}  # fmt: skip
    r = tool.client.post("/api/lti/platforms", json=body, headers=tool.admin())
    assert r.status_code == 422
    (error,) = r.json()["errors"]
    assert error["path"] == "auth_url"
    assert "https://" in error["message"]
    r = tool.client.post("/api/lti/platforms", json={**body, "auth_url": body["token_url"], "jwks_url": 3},
                         headers=tool.admin())  # fmt: skip
    assert r.status_code == 422
    assert [e["path"] for e in r.json()["errors"]] == ["jwks_url"]


def test_lti_command_private_addresses_need_allow_private_and_the_options_are_kept(tmp_path, capsys):
    data = ["--data-dir", str(tmp_path)]
    local = [
        "--issuer", "https://10.0.0.5", "--client-id", "c1", "--auth-url", "https://10.0.0.5/auth",
        "--token-url", "https://10.0.0.5/token", "--jwks-url", "https://10.0.0.5/jwks", "--deployment", "1",
    ]  # fmt: skip
    assert main(["register", *local, *data]) == 1
    err = capsys.readouterr().err
    assert err.startswith("issuer: 'https://10.0.0.5' is on a loopback, link-local or private address")
    assert "--allow-private" in err
    assert main(["register", *local, "--allow-private", "--trust-emails", *data]) == 0
    assert "trusts emails" in capsys.readouterr().out
    argv = ["register", *PLATFORM, "--deployment", "1", "--service-origin", "https://school.example.edu", *data]
    assert main(argv) == 0 and "service origins: https://school.example.edu" in capsys.readouterr().out


def test_lti_api_register_refuses_a_private_address_unless_allowed(tool):
    body = {"issuer": "https://169.254.169.254", "client_id": "c", "auth_url": "https://lms.example.edu/auth",
            "token_url": "https://lms.example.edu/token", "jwks_url": "https://lms.example.edu/jwks"}  # fmt: skip
    r = tool.client.post("/api/lti/platforms", json=body, headers=tool.admin())
    assert r.status_code == 422
    assert [e["path"] for e in r.json()["errors"]] == ["issuer"]
    r = tool.client.post("/api/lti/platforms", json={**body, "allow_private": True}, headers=tool.admin())
    assert r.status_code == 201
    assert r.json()["trust_emails"] is False
    assert tool.client.delete(f"/api/lti/platforms/{r.json()['id']}", headers=tool.admin()).status_code == 204
