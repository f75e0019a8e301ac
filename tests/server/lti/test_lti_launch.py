"""Launches through the real OIDC flow, against the service on loopback and a test platform: the one that
passes, and every one that must be refused, each refused with a page naming its check and nothing issued."""

from __future__ import annotations

import html
import time

import pytest

from tests.support.lti_platform import INSTRUCTOR, LTI, new_key

TA = "http://purl.imsglobal.org/vocab/lis/v2/membership/Instructor#TeachingAssistant"


def check_of(r) -> str | None:
    """The data-check of a refused launch's page (None on any other page)."""
    text = r.text
    at = text.find('data-check="')
    return text[at + 12 : text.index('"', at + 12)] if at >= 0 else None


def assert_refused(r, check: str, status: int = 400, words: str = "") -> None:
    assert r.status_code == status, (r.status_code, r.text)
    assert check_of(r) == check, r.text
    assert "<h1>The launch was refused</h1>" in r.text
    assert f"<strong>{check}</strong>: " in r.text
    assert words in html.unescape(r.text), r.text
    assert "set-cookie" not in r.headers  # no cookie, no session, no token
    assert "location" not in r.headers
    assert "token=" not in r.text
    assert "authorization" not in r.headers


def test_lti_launch_through_the_oidc_flow_opens_the_handler_page(tool, platform):
    r = platform.do_launch(tool.client, tool.url, roles=[INSTRUCTOR])
    assert r.status_code == 200, r.text
    assert "launched as instructor in Rendering 101" in r.text
    auth = platform.auth_requests[-1]
    assert {k: auth[k] for k in ("scope", "response_type", "response_mode", "prompt", "client_id")} == {
        "scope": "openid", "response_type": "id_token", "response_mode": "form_post", "prompt": "none",
        "client_id": platform.client_id,
    }  # fmt: skip
    assert auth["redirect_uri"] == tool.url + "/lti/launch"
    assert (auth["login_hint"], auth["lti_message_hint"]) == ("user-hint-1", "message-hint-1")
    assert len(auth["state"]) >= 43
    assert len(auth["nonce"]) >= 43  # 256 random bits each
    assert platform.jwks_hits == 1


def test_lti_launch_login_by_post_sets_the_state_cookie_and_a_launch_needs_it(tool, platform):
    """The login first looks for a cookie it set (does this browser keep the tool's cookies here?), then sets the
    one state cookie, `lti_state`; a launch whose browser lost it is refused (no Platform Storage was offered)."""
    login = {"iss": platform.issuer, "login_hint": "u", "target_link_uri": tool.url + "/lti/launch",
             "client_id": platform.client_id}  # fmt: skip
    r = tool.client.post(tool.url + "/lti/login", data=login)
    assert r.status_code == 302 and "lti_cookie_check=1" in r.headers["location"], r.headers
    assert r.headers["set-cookie"].startswith("lti_check=1;")
    assert not platform.auth_requests  # nothing kept yet
    r = tool.client.get(r.headers["location"], headers={"Cookie": "lti_check=1"})
    assert r.status_code == 302
    assert r.headers["location"].startswith(platform.auth_url + "?")
    cookie = next(c for c in r.headers.get_list("set-cookie") if c.startswith("lti_state="))
    state = dict(p.split("=", 1) for p in r.headers["location"].split("?", 1)[1].split("&"))["state"]
    assert cookie.startswith(f"lti_state={state};")
    for attribute in ("Secure", "HttpOnly", "SameSite=None", "Path=/lti/", "Max-Age=600", "Partitioned"):
        assert attribute in cookie
    r = platform.do_launch(tool.client, tool.url, method="POST", cookie=False)  # the cookie lost since the login
    assert_refused(r, "state", 400, "did not send back the cookie")
    assert platform.do_launch(tool.client, tool.url, method="POST").status_code == 200


def test_lti_launch_a_browser_that_keeps_no_cookie_is_offered_a_new_window(tool, platform):
    login = {"iss": platform.issuer, "login_hint": "u", "target_link_uri": tool.url + "/lti/launch",
             "client_id": platform.client_id, "lti_message_hint": "m&1"}  # fmt: skip
    r = tool.client.get(tool.url + "/lti/login", params={**login, "lti_cookie_check": "1"})  # no cookie came back
    assert r.status_code == 200
    assert 'data-check="cookie"' in r.text
    assert "set-cookie" not in r.headers
    link = html.unescape(r.text.split('id="lti-new-window" class="button" href="', 1)[1].split('"', 1)[0])
    assert 'target="_blank"' in r.text
    assert "lti_cookie_check" not in link
    assert "m%261" in link
    assert not platform.auth_requests  # no login kept
    r = tool.client.get(link)  # the new window: its own login, which sets its cookie first
    assert r.status_code == 302
    assert "lti_cookie_check=1" in r.headers["location"]


def test_lti_launch_a_forged_launch_meets_the_browser_s_own_state_cookie(tool, platform):
    """Login CSRF: an attacker's own login and launch, posted by the victim's browser. The victim's browser holds
    its own state cookie (one name for every state): the states differ, refused; it holds none: refused too."""
    checked = {"Cookie": "lti_check=1"}  # (the login's check passed)
    victim = tool.client.get(tool.url + "/lti/login", params={"iss": platform.issuer, "login_hint": "v",
                             "target_link_uri": "t", "lti_cookie_check": "1"}, headers=checked)  # fmt: skip
    victims = next(c for c in victim.headers.get_list("set-cookie") if c.startswith("lti_state="))
    for cookie in (victims.split(";", 1)[0], None):
        attacker = tool.client.get(tool.url + "/lti/login", params={"iss": platform.issuer, "login_hint": "a",
                                   "target_link_uri": "t", "lti_cookie_check": "1"},
                                   headers={"Cookie": "lti_check=1"})  # fmt: skip
        query = dict(p.split("=", 1) for p in attacker.headers["location"].split("?", 1)[1].split("&"))
        token = platform.launch_token(nonce=query["nonce"], sub="attacker")
        headers = {"Cookie": cookie} if cookie else {}
        r = tool.client.post(tool.url + "/lti/launch", data={"id_token": token, "state": query["state"]},
                             headers=headers)  # fmt: skip
        assert_refused(r, "state", 400)


def test_lti_launch_refused_for_a_service_url_off_the_platform(tool, platform):
    """The tool sends the platform's access token to its service URLs: a line item, the line items, the members
    or a deep-linking return URL elsewhere than the platform's registered origins is refused at the launch."""
    ags = "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint"
    nrps = "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice"
    elsewhere = "http://127.0.0.1:9/lineitems/li-1"  # loopback too, but another origin
    for overrides, name in (
        ({ags: {"scope": [], "lineitem": elsewhere}}, "lineitem"),
        ({ags: {"scope": [], "lineitems": "https://evil.example/items"}}, "lineitems"),
        ({nrps: {"context_memberships_url": "http://169.254.169.254/latest/meta-data"}}, "context_memberships_url"),
    ):
        r = platform.do_launch(tool.client, tool.url, overrides=overrides)
        assert_refused(r, "services", 400, f"the launch's {name} (")
        assert platform.url in html.unescape(r.text)  # the addresses it may be at
    r = platform.do_launch(tool.client, tool.url, roles=[INSTRUCTOR], message_type="LtiDeepLinkingRequest",
                           deep_linking={"deep_link_return_url": "https://evil.example/return"})  # fmt: skip
    assert_refused(r, "services", 400, "deep_link_return_url")
    assert platform.do_launch(tool.client, tool.url).status_code == 200  # its own URLs


def test_lti_launch_logins_from_one_address_are_capped(tool, platform, monkeypatch):
    from server.lti import store as lti_store

    monkeypatch.setattr(lti_store, "MAX_LOGINS_PER_ADDRESS", 2)
    with tool.lti.store._tx() as db:
        db.execute("DELETE FROM lti_logins")
    login = {"iss": platform.issuer, "login_hint": "u", "target_link_uri": "t", "lti_cookie_check": "1"}
    for _ in range(2):
        r = tool.client.get(tool.url + "/lti/login", params=login, headers={"Cookie": "lti_check=1"})
        assert r.status_code == 302
    r = tool.client.get(tool.url + "/lti/login", params=login, headers={"Cookie": "lti_check=1"})
    assert r.status_code == 429
    assert 'data-check="login"' in r.text
    assert int(r.headers["retry-after"]) > 590
    assert "set-cookie" not in r.headers
    with tool.lti.store._tx() as db:
        db.execute("DELETE FROM lti_logins")


def test_lti_launch_of_a_teaching_assistant_with_the_principal_role_is_a_ta(tool, platform):
    r = platform.do_launch(tool.client, tool.url, roles=[INSTRUCTOR, TA])
    assert r.status_code == 200
    assert "launched as ta in" in r.text


def test_lti_launch_refused_with_another_key(tool, platform):
    r = platform.do_launch(tool.client, tool.url, key=new_key(), kid=platform.key.kid)
    assert_refused(r, "signature", 401, "does not match")


def test_lti_launch_refused_for_an_unknown_kid_after_one_refetch(tool, platform):
    platform.do_launch(tool.client, tool.url)  # the key set is cached
    assert platform.jwks_hits == 1
    tool.lti.jwks.min_interval = 0  # (the cache's refetch interval is its own test's)
    try:
        r = platform.do_launch(tool.client, tool.url, key=new_key())
    finally:
        tool.lti.jwks.min_interval = 60.0
    assert_refused(r, "kid", 401, "has no key")
    assert platform.jwks_hits == 2  # fetched again exactly once


def test_lti_launch_follows_a_rotated_key(tool, platform):
    platform.do_launch(tool.client, tool.url)
    platform.key = new_key()
    platform.keys = [platform.key]
    tool.lti.jwks.min_interval = 0
    try:
        r = platform.do_launch(tool.client, tool.url)
    finally:
        tool.lti.jwks.min_interval = 60.0
    assert r.status_code == 200, r.text
    assert platform.jwks_hits == 2


def test_lti_launch_refused_when_expired(tool, platform):
    r = platform.do_launch(tool.client, tool.url, now=time.time() - 300 - 61)
    assert_refused(r, "exp", 400, "this launch expired at")


def test_lti_launch_refused_when_issued_in_the_future(tool, platform):
    r = platform.do_launch(tool.client, tool.url, now=time.time() + 61 + 5)
    assert_refused(r, "iat", 400, "in the future")


@pytest.mark.parametrize("skew", [-300 - 50, 50])
def test_lti_launch_accepts_clock_skew_within_the_leeway(tool, platform, skew):
    r = platform.do_launch(tool.client, tool.url, now=time.time() + skew)
    assert r.status_code == 200, r.text


def test_lti_launch_refused_when_replayed_with_a_second_login(tool, platform):
    assert platform.do_launch(tool.client, tool.url).status_code == 200
    replayed = platform.last["id_token"]
    r = platform.do_launch(tool.client, tool.url, token=replayed)
    assert_refused(r, "nonce", 400, "nonce")


def test_lti_launch_refused_when_the_nonce_was_used(tool, platform):
    """The same id_token and nonce again (its login's row put back, as a replayed state would): the nonce is
    seen already."""
    assert platform.do_launch(tool.client, tool.url).status_code == 200
    last = platform.last
    state, _ = tool.lti.store.new_login(platform.registered["id"], "x", tool.lti.clock())
    tool.lti.store.db.execute("UPDATE lti_logins SET nonce = ? WHERE state = ?", (last["nonce"], state))
    r = tool.client.post(
        tool.url + "/lti/launch",
        data={"id_token": last["id_token"], "state": state},
        headers={"Cookie": f"lti_state={state}"},
    )  # (the browser's own login, as it were)
    assert_refused(r, "nonce", 400, "<strong>nonce</strong>: this launch was used already")


def test_lti_launch_refused_when_its_state_comes_twice(tool, platform):
    assert platform.do_launch(tool.client, tool.url).status_code == 200
    last = platform.last
    r = tool.client.post(tool.url + "/lti/launch", data={"id_token": last["id_token"], "state": last["state"]})
    assert_refused(r, "state", 400, "used already")


def test_lti_launch_refused_without_state(tool, platform):
    r = tool.client.post(tool.url + "/lti/launch", data={"id_token": platform.launch_token(nonce="n")})
    assert_refused(r, "state", 400, "no state")


def test_lti_launch_refused_when_the_cookie_is_another_state(tool, platform):
    first = tool.client.get(tool.url + "/lti/login", params={"iss": platform.issuer, "login_hint": "u",
                            "target_link_uri": "t", "client_id": platform.client_id, "lti_cookie_check": "1"},
                            headers={"Cookie": "lti_check=1"})  # fmt: skip
    state = first.headers["location"].split("state=")[1].split("&")[0]
    nonce = first.headers["location"].split("nonce=")[1].split("&")[0]
    headers = {"Cookie": "lti_state=something-else"}
    data = {"id_token": platform.launch_token(nonce=nonce), "state": state}
    assert_refused(tool.client.post(tool.url + "/lti/launch", data=data, headers=headers), "state", 400, "browser")


def test_lti_launch_refused_for_another_audience(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={"aud": "someone-else", "azp": "someone-else"})
    assert_refused(r, "aud", 400, "someone-else")


def test_lti_launch_refused_for_several_audiences_without_azp(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={"aud": [platform.client_id, "other"]}, drop=["azp"])
    assert_refused(r, "azp", 400, "several audiences")


def test_lti_launch_refused_for_an_azp_that_is_not_the_tool(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={"aud": [platform.client_id, "other"], "azp": "other"})
    assert_refused(r, "azp", 400, "'other'")


def test_lti_launch_refused_for_an_unknown_deployment(tool, platform):
    r = platform.do_launch(tool.client, tool.url, deployment_id="deployment-9")
    assert_refused(r, "deployment_id", 400, "deployment-9")


def test_lti_login_refused_for_an_unknown_deployment(tool, platform):
    r = tool.client.get(tool.url + "/lti/login", params={"iss": platform.issuer, "login_hint": "u",
                        "target_link_uri": "t", "lti_deployment_id": "deployment-9"})  # fmt: skip
    assert_refused(r, "deployment_id", 400, "deployment-9")


def test_lti_launch_refused_for_another_message_type(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={LTI + "message_type": "LtiSubmissionReviewRequest"})
    assert_refused(r, "message_type", 400, "LtiSubmissionReviewRequest")


def test_lti_launch_refused_for_another_version(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={LTI + "version": "1.1"})
    assert_refused(r, "version", 400, "expected '1.3.0'")


def test_lti_launch_refused_without_a_resource_link_id(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={LTI + "resource_link": {"title": "no id"}})
    assert_refused(r, "resource_link", 400)


def test_lti_launch_refused_for_an_unknown_issuer(tool, platform):
    r = platform.do_launch(tool.client, tool.url, overrides={"iss": "https://lms.elsewhere.example"})
    assert_refused(r, "iss", 400, "not a registered platform")


def test_lti_login_refused_for_an_unknown_platform(tool, platform):
    r = tool.client.get(tool.url + "/lti/login", params={"iss": "https://nobody.example", "login_hint": "u",
                        "target_link_uri": "t"})  # fmt: skip
    assert_refused(r, "platform", 400, "no platform is registered")


def test_lti_launch_of_deep_linking_carries_its_settings(tool, platform):
    r = platform.do_launch(tool.client, tool.url, message_type="LtiDeepLinkingRequest")
    assert r.status_code == 200
    assert "LtiDeepLinkingRequest" in r.text


def test_lti_launch_pages_may_be_framed_by_the_platform_only(tool, platform):
    r = platform.do_launch(tool.client, tool.url)
    policy = r.headers["content-security-policy"]
    assert f"frame-ancestors 'self' {platform.issuer}" in policy
    assert "x-frame-options" not in r.headers
    api = tool.client.get("/api/health")
    assert "frame-ancestors 'none'" in api.headers["content-security-policy"]
    assert api.headers["x-frame-options"] == "DENY"


def test_lti_launch_refusal_page_escapes_what_the_token_says(tool, platform):
    r = platform.do_launch(tool.client, tool.url, deployment_id='<script>alert("x")</script>')
    assert_refused(r, "deployment_id", 400, '<script>alert("x")</script>')
    assert "<script>" not in r.text
    assert "&lt;script&gt;" in r.text
    assert '<html lang="en">' in r.text
    assert '<link rel="stylesheet" href="/css/app.css">' in r.text


def test_lti_launch_return_url_origin_may_frame_the_tool(tool, platform):
    """A hosted Canvas shows its courses at the school's address, which its registration does not name: the
    origin of a verified launch's return URL may frame the tool, from that launch's own answer on."""
    school = "https://school.example.edu"
    presentation = {"document_target": "iframe", "return_url": school + "/courses/1/external_content/success"}
    r = platform.do_launch(tool.client, tool.url, overrides={LTI + "launch_presentation": presentation})
    assert r.status_code == 200, r.text
    assert school in r.headers["content-security-policy"].split("frame-ancestors")[1].split(";")[0]
    assert school in tool.client.get("/course").headers["content-security-policy"]
    refused = platform.do_launch(tool.client, tool.url, overrides={"iss": "https://evil.example",
                                 LTI + "launch_presentation": {"return_url": "https://evil.example/x"}})  # fmt: skip
    assert check_of(refused) == "iss" and "evil.example" not in tool.client.get("/course").headers[
        "content-security-policy"]  # fmt: skip
