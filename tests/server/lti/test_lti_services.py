"""LTI Advantage calls against the test platform on loopback: access tokens (cached), scores, line items,
members page by page, and a deep-linking answer the platform verifies with the tool's published key."""

from __future__ import annotations

import httpx
import pytest

from server.lti.services import SCORE_SCOPE, ServiceClient, ServiceError, deep_link_response, score, scores_url
from tests.support.lti_platform import DL, LTI, NRPS_SCOPE


class Clock:
    def __init__(self, now: float):
        self.now = now

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def services(tool):
    import time

    clock = Clock(time.time())
    with httpx.Client(timeout=10) as http:
        client = ServiceClient(tool.lti.keys, http, clock)
        client.test_clock = clock
        yield client


def test_lti_services_access_token_is_cached_until_a_minute_before_expiry(services, platform):
    p = platform.registered
    token = services.access_token(p, [SCORE_SCOPE])
    assert services.access_token(p, [SCORE_SCOPE]) == token and len(platform.token_requests) == 1
    (request,) = platform.token_requests
    assert request["grant_type"] == "client_credentials"
    assert request["scope"] == SCORE_SCOPE
    assert services.access_token(p, [NRPS_SCOPE]) != token  # other scopes, another token
    services.test_clock.now += 3600 - 59  # within a minute of its expiry: a new one
    assert services.access_token(p, [SCORE_SCOPE]) != token and len(platform.token_requests) == 3


def test_lti_services_a_bad_assertion_is_refused_by_the_platform(services, platform):
    p = {**platform.registered, "client_id": "not-the-client"}
    with pytest.raises(ServiceError) as e:
        services.access_token(p, [SCORE_SCOPE])
    assert e.value.status == 401
    assert "invalid_client" in e.value.message


def test_lti_services_score_posted_with_increasing_timestamps(services, platform):
    p = platform.registered
    lineitem = f"{platform.url}/lineitems/li-1?context=course-1"
    assert scores_url(lineitem) == f"{platform.url}/lineitems/li-1/scores?context=course-1"
    first = score("student-1", 7, 10, services.test_clock.now, comment="two reflections missing")
    assert first["timestamp"].endswith("Z")
    assert len(first["timestamp"]) == len("2026-12-05T09:15:00.000Z")
    services.post_score(p, lineitem, first)
    services.post_score(p, lineitem, score("student-1", 9, 10, services.test_clock.now + 1))
    assert [(s["userId"], s["scoreGiven"], s["lineitem"]) for s in platform.scores] == [
        ("student-1", 7, "li-1"), ("student-1", 9, "li-1")]  # fmt: skip
    assert platform.scores[0] | {"lineitem": None} == first | {"lineitem": None}
    assert (first["activityProgress"], first["gradingProgress"]) == ("Completed", "FullyGraded")
    with pytest.raises(ServiceError) as e:  # not later than the last one
        services.post_score(p, lineitem, score("student-1", 5, 10, services.test_clock.now))
    assert e.value.status == 409


def test_lti_services_score_fails_with_the_platform_down(services, platform):
    platform.down = True
    with pytest.raises(ServiceError) as e:
        services.post_score(platform.registered, f"{platform.url}/lineitems/li-1", score("s", 1, 2, 0.0))
    assert e.value.status == 503
    assert "503" in e.value.message
    platform.stop()
    with pytest.raises(ServiceError) as e:
        services.post_score(platform.registered, f"{platform.url}/lineitems/li-1", score("s", 1, 2, 1.0))
    assert e.value.status == 0
    assert "no answer" in e.value.message


def test_lti_services_line_items_read_and_made(services, platform):
    p, url = platform.registered, f"{platform.url}/lineitems?context=course-1"
    assert [i["label"] for i in services.line_items(p, url)] == ["Ray trees"]
    made = services.create_line_item(p, url, "Radiosity", 20, resource_link_id="link-2", tag="hw2")
    assert made["id"].startswith(platform.url + "/lineitems/li-")
    assert made["scoreMaximum"] == 20
    assert [i["label"] for i in services.line_items(p, url, resource_link_id="link-2")] == ["Radiosity"]
    services.post_score(p, made["id"], score("student-2", 15, 20, 1.0))
    assert platform.scores[-1]["lineitem"] == made["id"].rsplit("/", 1)[1]


def test_lti_services_members_across_pages(services, platform):
    members = services.members(platform.registered, f"{platform.url}/memberships/course-1?limit=2")
    assert [m["user_id"] for m in members] == [f"user-{i}" for i in range(5)]  # 3 pages of at most 2
    assert members[0] == {
        "user_id": "user-0", "name": "Person 0", "email": "person0@example.edu", "given_name": "Person",
        "family_name": "0", "roles": ["http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"],
        "status": "Active", "lis_person_sourcedid": "sis-0",
    }  # fmt: skip
    assert len(services.members(platform.registered, f"{platform.url}/memberships/course-1?limit=2", 2)) == 4


def test_lti_services_deep_link_response_verified_by_the_platform(tool, platform):
    settings = {"deep_link_return_url": platform.url + "/deep_link_return", "data": "opaque-data-1"}
    items = [{"type": "ltiResourceLink", "title": "Ray trees", "url": tool.url + "/lti/launch",
              "custom": {"assignment": "a1"}}]  # fmt: skip
    jwt = deep_link_response(tool.lti.keys, platform.registered, platform.deployment_id, settings, items, 1e9)
    r = httpx.post(settings["deep_link_return_url"], data={"JWT": jwt}, timeout=10)
    assert r.status_code == 200, r.text
    (claims,) = platform.deep_links
    assert claims[DL + "content_items"] == items
    assert claims[DL + "data"] == "opaque-data-1"
    assert claims[LTI + "message_type"] == "LtiDeepLinkingResponse"
    assert claims["exp"] - claims["iat"] == 600


def test_lti_services_deep_link_form_posts_the_answer_to_the_platform(tool, platform):
    import re

    from server.lti.pages import deep_link_form

    return_url = platform.url + "/deep_link_return"
    jwt = deep_link_response(tool.lti.keys, platform.registered, platform.deployment_id, {}, [], 1e9)
    html = deep_link_form(return_url, jwt, "Ray trees <1>").html
    assert "Ray trees &lt;1&gt;" in html
    assert "<script" not in html
    action = re.search(r'<form method="post" action="([^"]+)">', html)[1]
    value = re.search(r'name="JWT" value="([^"]+)"', html)[1]
    assert (action, value) == (return_url, jwt)
    assert httpx.post(action, data={"JWT": value}, timeout=10).status_code == 200
    assert platform.deep_links[-1][DL + "content_items"] == []


def test_lti_services_a_revoked_token_is_replaced_once(services, platform):
    p, lineitem = platform.registered, f"{platform.url}/lineitems/li-1"
    services.post_score(p, lineitem, score("student-1", 1, 10, 1.0))
    platform.tokens.clear()  # the platform forgets every token it gave
    services.post_score(p, lineitem, score("student-1", 2, 10, 2.0))
    assert len(platform.token_requests) == 2
    assert len(platform.scores) == 2


def test_lti_services_staff_see_the_status_and_a_short_reason_not_the_platform_s_body(services, platform):
    platform.down = True  # its answer's body: {"error": "down for maintenance"}
    with pytest.raises(ServiceError) as e:
        services.post_score(platform.registered, f"{platform.url}/lineitems/li-1", score("s", 1, 2, 0.0))
    assert e.value.status == 503 and "HTTP 503 (Service Unavailable" in e.value.message, e.value.message
    assert "maintenance" not in e.value.message
    assert "{" not in e.value.message


def test_lti_services_send_the_platform_s_token_to_its_own_origins_only(services, platform):
    """A score, a line item or the members at another origin (another port of loopback here) are refused before
    anything is sent: no access token is even asked for."""
    from tests.support.lti_platform import LoopbackServer

    seen = []

    async def elsewhere(scope, receive, send):  # an ASGI app that records what comes
        if scope["type"] == "http":
            seen.append(scope["path"])
            await send({"type": "http.response.start", "status": 204, "headers": []})
            await send({"type": "http.response.body", "body": b""})

    with LoopbackServer(elsewhere) as other:
        p = platform.registered
        calls = (
            lambda: services.post_score(p, f"{other.url}/lineitems/li-1", score("s", 1, 2, 0.0)),
            lambda: services.line_items(p, f"{other.url}/lineitems"),
            lambda: services.members(p, f"{other.url}/memberships/course-1"),
        )
        for call in calls:
            with pytest.raises(ServiceError) as e:
                call()
            assert "not at the platform's registered addresses" in e.value.message
            assert platform.url in e.value.message
    assert seen == []
    assert platform.token_requests == []
