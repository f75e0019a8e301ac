"""LTI Advantage: the calls the tool makes to a platform, each with an OAuth 2 access token.

- Access tokens (IMS Security Framework §4.1): the client-credentials grant with a JWT client assertion
  (RFC 7523) signed by the tool's key, cached per (platform, scopes) until a minute before they expire.
- Assignment and Grade Services 2.0: a score posted to a line item (`post_score`, `score`), the line items of a
  context read or made (`line_items`, `create_line_item`).
- Names and Role Provisioning Services 2.0: a context's members, page by page (`members`).
- Deep Linking 2.0: the signed LtiDeepLinkingResponse that carries the chosen content items back
  (`deep_link_response`; the browser form-posts it to the settings' deep_link_return_url).

A platform that answers with an error, or not at all, raises `ServiceError(status, message)` (status 0: no
answer). Every wait is bounded (10 s), and so is every answer's size.
"""

from __future__ import annotations

import json
import logging
import re
import secrets
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from urllib.parse import urljoin, urlsplit, urlunsplit

import httpx

from server.lti.http import TooLarge, get_json, read_bounded
from server.lti.keys import ToolKeys
from server.lti.launch import DEPLOYMENT_ID, DL, MESSAGE_TYPE, VERSION
from server.lti.store import PlatformRow, on_platform, platform_origins

log = logging.getLogger("server.lti")

AGS = "https://purl.imsglobal.org/spec/lti-ags/scope/"
SCORE_SCOPE = AGS + "score"
LINEITEM_SCOPE = AGS + "lineitem"
LINEITEM_READ_SCOPE = AGS + "lineitem.readonly"
RESULT_READ_SCOPE = AGS + "result.readonly"
NRPS_SCOPE = "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly"
SCORE_TYPE = "application/vnd.ims.lis.v1.score+json"
LINEITEM_TYPE = "application/vnd.ims.lis.v2.lineitem+json"
LINEITEMS_TYPE = "application/vnd.ims.lis.v2.lineitemcontainer+json"
MEMBERS_TYPE = "application/vnd.ims.lti-nrps.v2.membershipcontainer+json"
ASSERTION_TYPE = "urn:ietf:params:oauth:client-assertion-type:jwt-bearer"
TIMEOUT = 10.0  # seconds, every call
MAX_BYTES = 4_000_000  # bytes of one answer (a page of members, a list of line items, a token)
TOKEN_MARGIN = 60  # seconds: a cached token is used until this long before it expires
MEMBER_FIELDS = ("user_id", "name", "email", "given_name", "family_name", "roles", "status", "lis_person_sourcedid")


class ServiceError(Exception):
    """A platform's service refused or failed a call: its HTTP status (0 when there was no answer) and why."""

    def __init__(self, status: int, message: str):
        super().__init__(f"{status}: {message}")
        self.status, self.message = status, message


class ServiceClient:
    """The tool's calls to platforms' services, with access tokens from their token URLs (`clock`: Unix time)."""

    def __init__(self, keys: ToolKeys, http: httpx.Client | None = None, clock: Callable[[], float] = time.time):
        self.keys, self.clock = keys, clock
        self.http = http or httpx.Client(timeout=TIMEOUT, follow_redirects=False)
        self._tokens: dict[tuple[str, tuple[str, ...]], tuple[str, float]] = {}
        self._lock = threading.Lock()

    # -- access tokens ---------------------------------------------------------------------------------

    def access_token(self, platform: PlatformRow, scopes: list[str]) -> str:
        """A bearer token of `platform` for `scopes`: cached, or asked for with a signed client assertion."""
        key = (platform["id"], tuple(sorted(scopes)))
        now = self.clock()
        with self._lock:
            cached = self._tokens.get(key)
            if cached and cached[1] - TOKEN_MARGIN > now:
                return cached[0]
        assertion = self.keys.sign(
            {
                "iss": platform["client_id"],
                "sub": platform["client_id"],
                "aud": platform["token_url"],
                "iat": int(now),
                "exp": int(now) + 300,
                "jti": secrets.token_urlsafe(16),
            }
        )
        form = {
            "grant_type": "client_credentials",
            "client_assertion_type": ASSERTION_TYPE,
            "client_assertion": assertion,
            "scope": " ".join(scopes),
        }
        data = self._call("POST", platform["token_url"], "the access token", data=form)
        token = data.get("access_token") if isinstance(data, dict) else None
        if not isinstance(data, dict) or not isinstance(token, str) or not token:
            raise ServiceError(502, f"the platform's token URL {platform['token_url']} answered without access_token")
        expires_in = data.get("expires_in", 3600)
        expires_in = expires_in if isinstance(expires_in, int | float) and not isinstance(expires_in, bool) else 3600
        with self._lock:
            self._tokens[key] = (token, now + expires_in)
        return token

    def _call(self, method: str, url: str, what: str, **kwargs) -> object:
        """One HTTP call: its JSON answer (None for an empty body); ServiceError for any failure."""
        try:
            with self.http.stream(method, url, timeout=TIMEOUT, **kwargs) as response:
                body = read_bounded(response, MAX_BYTES)
        except httpx.HTTPError as e:
            raise ServiceError(0, f"{what}: no answer from {url} ({type(e).__name__}: {e})") from None
        except TooLarge as e:
            raise ServiceError(502, f"{what}: the answer of {url} is too large ({e})") from None
        if not response.is_success:  # its status and reason for the staff; its body (anything) for the log only
            log.info("%s: %s answered HTTP %d: %r", what, url, response.status_code, body[:300])
            raise ServiceError(response.status_code, f"{what}: the platform answered HTTP {response.status_code} "
                               f"{_reason(response, body)}")  # fmt: skip
        if not body.strip():
            return None
        try:
            return json.loads(body)
        except ValueError:
            raise ServiceError(502, f"{what}: the answer of {url} is not JSON") from None

    def _authorized(self, platform: PlatformRow, scope: str, headers: dict) -> dict:
        return {**headers, "Authorization": f"Bearer {self.access_token(platform, [scope])}"}

    def _send(
        self, platform: PlatformRow, scope: str, method: str, url: str, what: str, headers: dict, **kwargs
    ) -> object:
        """`_call` with a bearer token for `scope`, only to the platform's own origins (ServiceError otherwise);
        a 401 (a token the platform no longer honours) drops the cached token and tries once more with a new one."""
        _on_platform(platform, url, what)
        for attempt in (1, 2):
            try:
                return self._call(method, url, what, headers=self._authorized(platform, scope, headers), **kwargs)
            except ServiceError as e:
                if e.status != 401 or attempt == 2:
                    raise
                with self._lock:
                    self._tokens.pop((platform["id"], (scope,)), None)
        raise AssertionError("unreachable")

    # -- Assignment and Grade Services ------------------------------------------------------------------

    def post_score(self, platform: PlatformRow, lineitem_url: str, score: dict) -> None:
        """POST `score` (see `score()`) to the line item's scores (AGS 2.0 §3.4)."""
        headers = {"Content-Type": SCORE_TYPE}
        self._send(platform, SCORE_SCOPE, "POST", scores_url(lineitem_url), "the score", headers, content=_json(score))

    def line_items(self, platform: PlatformRow, lineitems_url: str, resource_link_id: str | None = None) -> list[dict]:
        """The line items of a context (those of one resource link when given)."""
        params = {"resource_link_id": resource_link_id} if resource_link_id else None
        headers = {"Accept": LINEITEMS_TYPE}
        data = self._send(platform, LINEITEM_SCOPE, "GET", lineitems_url, "the line items", headers, params=params)
        if not isinstance(data, list):
            raise ServiceError(502, f"the line items: {lineitems_url} answered with no list of line items")
        return [item for item in data if isinstance(item, dict)]

    def create_line_item(
        self, platform: PlatformRow, lineitems_url: str, label: str, score_maximum: float,
        resource_link_id: str | None = None, tag: str | None = None, resource_id: str | None = None,
    ) -> dict:  # fmt: skip
        """A new line item in the context (for a launch that has `lineitems` but no `lineitem`): the platform's
        answer, whose `id` is the line item's URL."""
        item = {"label": label, "scoreMaximum": score_maximum}
        item |= {k: v for k, v in (("resourceLinkId", resource_link_id), ("tag", tag), ("resourceId", resource_id))
                 if v}  # fmt: skip
        headers = {"Content-Type": LINEITEM_TYPE, "Accept": LINEITEM_TYPE}
        data = self._send(
            platform, LINEITEM_SCOPE, "POST", lineitems_url, "the new line item", headers, content=_json(item)
        )
        if not isinstance(data, dict) or not isinstance(data.get("id"), str):
            raise ServiceError(502, f"the new line item: {lineitems_url} answered without the item's id")
        return data

    # -- Names and Role Provisioning Services --------------------------------------------------------------

    def members(self, platform: PlatformRow, memberships_url: str, max_pages: int = 50) -> list[dict]:
        """The context's members (NRPS 2.0), following `Link: <...>; rel="next"` for at most `max_pages` pages,
        each of at most MAX_BYTES bytes, on the memberships URL's own host only (the token goes nowhere else)."""
        origin = urlsplit(memberships_url)[:2]
        _on_platform(platform, memberships_url, "the members")
        headers = self._authorized(platform, NRPS_SCOPE, {"Accept": MEMBERS_TYPE})
        out, url = [], memberships_url
        for _ in range(max_pages):
            try:
                response, data = get_json(self.http, url, MAX_BYTES, headers, TIMEOUT)
            except httpx.HTTPError as e:
                raise ServiceError(0, f"the members: no answer from {url} ({type(e).__name__}: {e})") from None
            except (TooLarge, ValueError) as e:
                raise ServiceError(502, f"the members: the answer of {url} is too large or not JSON ({e})") from None
            if data is None:
                raise ServiceError(response.status_code, f"the members: {url} answered HTTP {response.status_code}")
            members = data.get("members") if isinstance(data, dict) else None
            out += [_member(m) for m in members or [] if isinstance(m, dict)]
            following = response.links.get("next", {}).get("url")
            if not following:
                return out
            url = urljoin(url, following)
            if urlsplit(url)[:2] != origin:
                raise ServiceError(502, f"the members: the next page {url} is on another host than {memberships_url}")
        log.warning("members of %s: stopped after %d pages", memberships_url, max_pages)
        return out


def _on_platform(platform: PlatformRow, url: str, what: str) -> None:
    """ServiceError unless `url` is at one of the platform's registered origins (its token goes nowhere else)."""
    if not on_platform(platform, url):
        raise ServiceError(0, f"{what}: {url[:200]} is not at the platform's registered addresses "
                           f"({', '.join(platform_origins(platform))}); nothing was sent")  # fmt: skip


def _reason(response: httpx.Response, body: bytes) -> str:
    """A short reason for a refused call: the HTTP reason phrase, and an OAuth-style `error` code when the
    platform's JSON answer names one (a word of lower-case letters and `_`, as OAuth 2 error codes are)."""
    try:
        data = json.loads(body) if body.strip() else None
    except ValueError:
        data = None
    code = data.get("error") if isinstance(data, dict) else None
    code = code if isinstance(code, str) and re.fullmatch(r"[a-z_]{1,40}", code) else None
    parts = [p for p in (response.reason_phrase, code) if p]
    return f"({', '.join(parts)})" if parts else ""


def _member(m: dict) -> dict:
    return {k: m[k] for k in MEMBER_FIELDS if k in m}


def _json(value: object) -> bytes:
    return json.dumps(value, separators=(",", ":")).encode()


def scores_url(lineitem_url: str) -> str:
    """The scores endpoint of a line item: `/scores` added to its path, its query kept after it."""
    parts = urlsplit(lineitem_url)
    return urlunsplit(parts._replace(path=parts.path.rstrip("/") + "/scores"))


def iso_time(t: float | datetime) -> str:
    """ISO 8601 in UTC with milliseconds and Z (2026-12-05T09:15:00.000Z), as AGS's timestamps are."""
    when = t if isinstance(t, datetime) else datetime.fromtimestamp(t, UTC)
    return when.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def score(user_id: str, given: float, maximum: float, timestamp_iso: str | float | datetime, comment=None) -> dict:
    """A Score (AGS 2.0 §3.4): a completed, fully graded activity of `user_id`. `timestamp_iso`: ISO 8601 text,
    or a time (Unix seconds or a datetime) written as one; platforms refuse a timestamp not later than the last."""
    stamp = timestamp_iso if isinstance(timestamp_iso, str) else iso_time(timestamp_iso)
    out = {
        "userId": user_id,
        "scoreGiven": given,
        "scoreMaximum": maximum,
        "activityProgress": "Completed",
        "gradingProgress": "FullyGraded",
        "timestamp": stamp,
    }
    if comment:
        out["comment"] = comment
    return out


# -- Deep Linking ------------------------------------------------------------------------------------------


def deep_link_response(
    keys: ToolKeys, platform: PlatformRow, deployment_id: str, settings: dict, items: list[dict], now: float
) -> str:
    """The LtiDeepLinkingResponse JWT (Deep Linking 2.0 §4.2) carrying `items` back to the platform."""
    claims = {
        "iss": platform["client_id"],
        "aud": platform["issuer"],
        "iat": int(now),
        "exp": int(now) + 600,
        "nonce": secrets.token_urlsafe(16),
        DEPLOYMENT_ID: deployment_id,
        MESSAGE_TYPE: "LtiDeepLinkingResponse",
        VERSION: "1.3.0",
        DL + "content_items": items,
    }
    if "data" in settings:
        claims[DL + "data"] = settings["data"]
    return keys.sign(claims)
