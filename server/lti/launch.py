"""A launch, checked: the OIDC login's authentication request, the platforms' key sets, and the id_token.

LTI 1.3 (IMS LTI Core 1.3 §5, and the IMS Security Framework §5.1) launches in three steps: the platform calls
the tool's login URL (third-party initiated login), the tool redirects the browser to the platform's auth URL
with a `state` and a `nonce` (`auth_request_url`), and the platform form-posts a signed id_token back to the
tool's launch URL. `verify_launch` checks that token: its signature by the platform's key (`JwksCache`), who
issued it and for whom, its times, its nonce (once), its deployment and its message. Each failed check raises a
`LaunchError` naming the check and saying, in plain words, what was expected and what came.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any
from urllib.parse import urlencode

import httpx
from joserfc import jws, jwt
from joserfc.errors import BadSignatureError, InvalidKeyIdError, JoseError
from joserfc.jwk import KeySet

from server.lti.http import TooLarge, get_json
from server.lti.roles import course_role
from server.lti.store import LoginRow, LtiStore, PlatformRow, on_platform, platform_origins

log = logging.getLogger("server.lti")

LTI = "https://purl.imsglobal.org/spec/lti/claim/"
DL = "https://purl.imsglobal.org/spec/lti-dl/claim/"
AGS_CLAIM = "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint"
NRPS_CLAIM = "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice"
DEPLOYMENT_ID = LTI + "deployment_id"
MESSAGE_TYPE = LTI + "message_type"
VERSION = LTI + "version"
RESOURCE_LINK = LTI + "resource_link"
DL_SETTINGS = DL + "deep_linking_settings"
MESSAGE_TYPES = ("LtiResourceLinkRequest", "LtiDeepLinkingRequest")
ALG = "RS256"  # the one algorithm LTI 1.3 platforms sign with (Security Framework §6.1)
JWKS_TIMEOUT = 5.0  # seconds
JWKS_MAX_BYTES = 65536
MAX_AGE = 86400  # seconds: an id_token issued longer ago than this (plus the leeway) is refused
UNAUTHORIZED = ("signature", "kid", "jwks")  # checks whose failure is a 401 (the others a 400)


class LaunchError(Exception):
    """A refused launch: `check` names the failed check ("nonce"), `message` says it for a person."""

    def __init__(self, check: str, message: str):
        super().__init__(f"{check}: {message}")
        self.check, self.message = check, message

    @property
    def status(self) -> int:
        return 401 if self.check in UNAUTHORIZED else 400


# -- the OIDC authentication request ------------------------------------------------------------------


def auth_request_url(
    platform: PlatformRow, *, login_hint: str, lti_message_hint: str | None, state: str, nonce: str, redirect_uri: str,
    client_id: str,
) -> str:  # fmt: skip
    """The platform's auth URL with the OIDC authentication request's parameters (LTI Core 1.3 §5.1.1.2)."""
    params = {
        "scope": "openid",
        "response_type": "id_token",
        "response_mode": "form_post",
        "prompt": "none",
        "client_id": client_id,
        "redirect_uri": redirect_uri,
        "login_hint": login_hint,
        "state": state,
        "nonce": nonce,
    }
    if lti_message_hint:
        params["lti_message_hint"] = lti_message_hint
    url = platform["auth_url"]
    return url + ("&" if "?" in url else "?") + urlencode(params)


# -- the platforms' key sets -----------------------------------------------------------------------------


def fetch_jwks(url: str) -> object:
    """A platform's JWKS from `url` (httpx: 5 s, at most 64 KiB, JSON, checked to be a key set by
    JwksCache._import); LaunchError("jwks") else."""
    try:
        with httpx.Client(timeout=JWKS_TIMEOUT, follow_redirects=False) as client:
            response, data = get_json(client, url, JWKS_MAX_BYTES, {"Accept": "application/json"}, JWKS_TIMEOUT)
    except httpx.HTTPError as e:
        raise LaunchError("jwks", f"the platform's key set at {url} could not be fetched ({e})") from None
    except TooLarge as e:
        raise LaunchError("jwks", f"the platform's key set at {url} is too large ({e})") from None
    except ValueError:
        raise LaunchError("jwks", f"the platform's key set at {url} is not JSON") from None
    if data is None:
        raise LaunchError("jwks", f"the platform's key set at {url} answered HTTP {response.status_code}")
    return data


class JwksCache:
    """Platforms' key sets by URL. A key id not in the cached set has the set fetched again, once per call and at
    most once per `min_interval` seconds per URL (`clock`), so forged key ids cannot make the tool fetch in a
    loop; a platform that rotates its key is followed within that time."""

    def __init__(
        self, fetch: Callable[[str], object] | None = None, min_interval: float = 60.0,
        clock: Callable[[], float] = time.monotonic,
    ):  # fmt: skip
        self.fetch, self.min_interval, self.clock = fetch or fetch_jwks, min_interval, clock
        self._sets: dict[str, KeySet] = {}
        self._fetched: dict[str, float] = {}
        self._locks: dict[str, threading.Lock] = {}  # one per URL: a slow platform holds up its own launches only
        self._lock = threading.Lock()

    def key_set(self, url: str, kid: str) -> KeySet:
        """The key set of `url` that has `kid` (LaunchError "kid" when even a fresh one has not, "jwks" when it
        cannot be had)."""
        with self._lock:
            lock = self._locks.setdefault(url, threading.Lock())
        with lock:
            cached = self._sets.get(url)
            if cached is not None and _has_kid(cached, kid):
                return cached
            last = self._fetched.get(url)
            if cached is not None and last is not None and self.clock() - last < self.min_interval:
                raise LaunchError(
                    "kid", f"the platform's key set ({url}) has no key '{kid}' (fetched again at most every "
                    f"{self.min_interval:g} s)",
                )  # fmt: skip
            self._fetched[url] = self.clock()
            fresh = self._import(url, self.fetch(url))
            self._sets[url] = fresh
        if not _has_kid(fresh, kid):
            known = ", ".join(str(k.kid) for k in fresh) or "none"
            raise LaunchError("kid", f"the platform's key set ({url}) has no key '{kid}'; it has {known}")
        return fresh

    @staticmethod
    def _import(url: str, data: object) -> KeySet:
        if not isinstance(data, dict) or not isinstance(data.get("keys"), list):
            raise LaunchError("jwks", f'the platform\'s key set at {url} is not a JWKS ({{"keys": [...]}})')
        try:
            return KeySet.import_key_set({"keys": [k for k in data["keys"] if isinstance(k, dict) and k.get("kid")]})
        except (JoseError, ValueError, TypeError, KeyError) as e:
            raise LaunchError("jwks", f"the platform's key set at {url} has no usable key ({e})") from None


def _has_kid(keys: KeySet, kid: str) -> bool:
    return any(k.kid == kid for k in keys)


# -- the launch --------------------------------------------------------------------------------------------


@dataclass
class Launch:
    """A verified launch: who (sub, names, email, roles), where (context, resource link, deployment), and what
    the platform offers back (AGS for grades, NRPS for members, deep-linking settings); `claims`: all of it."""

    platform: PlatformRow
    deployment_id: str
    message_type: str  # LtiResourceLinkRequest or LtiDeepLinkingRequest
    sub: str  # the user's id at the platform (may be "" for an anonymous deep-linking launch)
    name: str | None
    email: str | None
    given_name: str | None
    family_name: str | None
    roles: list[str]  # LIS role URIs
    context: dict | None  # {id, title, label}: the course
    resource_link: dict | None  # {id, title}: the link in the course that was clicked
    custom: dict
    target_link_uri: str | None
    ags: dict | None  # {scope: [...], lineitems, lineitem}: Assignment and Grade Services
    nrps: dict | None  # {context_memberships_url}: Names and Role Provisioning Services
    deep_linking: dict | None  # deep_linking_settings: deep_link_return_url, accept_types, data...
    claims: dict = field(repr=False)

    @property
    def course_role(self) -> str | None:
        return course_role(self.roles)

    @classmethod
    def from_claims(cls, platform: PlatformRow, claims: dict) -> Launch:
        context = _dict(claims.get(LTI + "context"))
        link = _dict(claims.get(RESOURCE_LINK))
        ags = _dict(claims.get(AGS_CLAIM))
        nrps = _dict(claims.get(NRPS_CLAIM))
        roles = claims.get(LTI + "roles")
        return cls(
            platform=platform,
            deployment_id=claims[DEPLOYMENT_ID],
            message_type=claims[MESSAGE_TYPE],
            sub=str(claims.get("sub") or ""),
            name=_text(claims.get("name")),
            email=_text(claims.get("email")),
            given_name=_text(claims.get("given_name")),
            family_name=_text(claims.get("family_name")),
            roles=[r for r in roles if isinstance(r, str)] if isinstance(roles, list) else [],
            context={k: _text(context.get(k)) for k in ("id", "title", "label")} if context else None,
            resource_link={k: _text(link.get(k)) for k in ("id", "title")} if link else None,
            custom=_dict(claims.get(LTI + "custom")) or {},
            target_link_uri=_text(claims.get(LTI + "target_link_uri")),
            ags={
                "scope": [s for s in ags.get("scope") or [] if isinstance(s, str)],
                "lineitems": _text(ags.get("lineitems")),
                "lineitem": _text(ags.get("lineitem")),
            }
            if ags
            else None,
            nrps={"context_memberships_url": _text(nrps.get("context_memberships_url"))} if nrps else None,
            deep_linking=_dict(claims.get(DL_SETTINGS)),
            claims=claims,
        )


def _dict(value: Any) -> dict | None:
    return value if isinstance(value, dict) else None


def _text(value: Any) -> str | None:
    return value if isinstance(value, str) else None


def _when(t: float) -> str:
    return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _peek(id_token: str) -> tuple[dict, dict]:
    """The token's header and claims, unverified (to find its platform and key)."""
    try:
        obj = jws.extract_compact(id_token.encode("ascii"))
        claims = json.loads(obj.payload)
    except (JoseError, ValueError, TypeError, UnicodeError):
        raise LaunchError("id_token", "the id_token is not a JSON Web Token (header.payload.signature)") from None
    if not isinstance(claims, dict):
        raise LaunchError("id_token", "the id_token's payload is not a JSON object")
    return obj.headers(), claims


def verify_launch(
    id_token: str, *, store: LtiStore, jwks: JwksCache, state_row: LoginRow, now: float, leeway: float
) -> Launch:
    """The launch that `id_token` carries, each check passed, for the login `state_row` (LtiStore.take_login),
    its nonce used up; LaunchError for the first check that fails. `leeway`: seconds of clock difference allowed."""
    if not isinstance(id_token, str) or not id_token:
        raise LaunchError("id_token", "the launch carries no id_token")
    header, unverified = _peek(id_token)
    platform = store.platform(state_row["platform_id"])
    if platform is None:
        raise LaunchError("platform", "the platform this login was started for is no longer registered")
    _check_issuer(unverified, platform, store)
    client_id = platform["client_id"]
    aud = unverified.get("aud")
    auds = [aud] if isinstance(aud, str) else aud if isinstance(aud, list) else []
    if client_id not in auds:
        raise LaunchError("aud", f"the token is for {auds or 'no audience'}, not this tool's client id '{client_id}'")
    azp = unverified.get("azp")
    if len(auds) > 1 and azp is None:
        raise LaunchError("azp", f"the token names several audiences ({', '.join(map(str, auds))}) and no azp")
    if azp is not None and azp != client_id:
        raise LaunchError("azp", f"the token's authorized party (azp) is '{azp}', not this tool's '{client_id}'")

    claims = _verified(id_token, header, platform, jwks)
    _check_times(claims, now, leeway)
    if claims.get("nonce") != state_row["nonce"]:
        raise LaunchError("nonce", "the token's nonce is not the one of its login (a launch replayed with another)")
    deployment = claims.get(DEPLOYMENT_ID)
    if deployment not in platform["deployment_ids"]:
        known = ", ".join(platform["deployment_ids"]) or "none"
        raise LaunchError("deployment_id", f"deployment '{deployment}' is not registered for this platform ({known})")
    _check_message(claims)
    exp = claims["exp"]
    if not store.use_nonce(platform["id"], claims["nonce"], float(exp), now):
        raise LaunchError("nonce", "this launch was used already (its nonce was seen before)")
    return Launch.from_claims(platform, claims)


def _check_issuer(claims: dict, platform: PlatformRow, store: LtiStore) -> None:
    iss = claims.get("iss")
    if iss == platform["issuer"]:
        return
    if not isinstance(iss, str) or not any(p["issuer"] == iss for p in store.platforms()):
        raise LaunchError("iss", f"the token's issuer {iss!r} is not a registered platform")
    raise LaunchError("iss", f"this login was started for {platform['issuer']}, but the token comes from {iss}")


def _verified(id_token: str, header: dict, platform: PlatformRow, jwks: JwksCache) -> dict:
    """The token's claims, its RS256 signature checked with the platform's key of its `kid`."""
    alg = header.get("alg")
    if alg != ALG:
        raise LaunchError("signature", f"the token is signed with {alg!r}; only {ALG} is accepted")
    kid = header.get("kid")
    if not isinstance(kid, str) or not kid:
        raise LaunchError("kid", "the token's header names no key id (kid)")
    keys = jwks.key_set(platform["jwks_url"], kid)
    try:
        return jwt.decode(id_token, keys, algorithms=[ALG]).claims
    except BadSignatureError:
        raise LaunchError("signature", f"the token's signature does not match the platform's key '{kid}'") from None
    except InvalidKeyIdError:
        raise LaunchError("kid", f"the platform's key '{kid}' is not an RS256 signing key") from None
    except (JoseError, ValueError) as e:
        raise LaunchError("id_token", f"the id_token could not be read ({e})") from None


def _check_times(claims: dict, now: float, leeway: float) -> None:
    exp, iat = claims.get("exp"), claims.get("iat")
    if not isinstance(exp, int | float) or isinstance(exp, bool):
        raise LaunchError("exp", "the token has no expiry time (exp)")
    if exp <= now - leeway:
        raise LaunchError(
            "exp", f"this launch expired at {_when(exp)}, {now - exp:.0f} s ago (the server allows {leeway:g} s "
            "of clock difference); launch again from the course",
        )  # fmt: skip
    if not isinstance(iat, int | float) or isinstance(iat, bool):
        raise LaunchError("iat", "the token has no issue time (iat)")
    if iat > now + leeway:
        raise LaunchError(
            "iat", f"the token was issued {iat - now:.0f} s in the future ({_when(iat)}; the server allows "
            f"{leeway:g} s of clock difference): the platform's clock or this server's is wrong",
        )  # fmt: skip
    if iat <= now - MAX_AGE - leeway:
        raise LaunchError("iat", f"the token was issued at {_when(iat)}, more than a day ago")


def _check_message(claims: dict) -> None:
    kind = claims.get(MESSAGE_TYPE)
    if kind not in MESSAGE_TYPES:
        raise LaunchError("message_type", f"the message type is {kind!r}; expected one of {', '.join(MESSAGE_TYPES)}")
    version = claims.get(VERSION)
    if version != "1.3.0":
        raise LaunchError("version", f"the LTI version is {version!r}; expected '1.3.0'")
    if kind == "LtiResourceLinkRequest":
        link = claims.get(RESOURCE_LINK)
        if not isinstance(link, dict) or not isinstance(link.get("id"), str) or not link["id"]:
            raise LaunchError("resource_link", "a resource link launch must carry its resource link's id")
    else:
        settings = claims.get(DL_SETTINGS)
        if not isinstance(settings, dict) or not isinstance(settings.get("deep_link_return_url"), str):
            raise LaunchError("deep_linking", "a deep linking launch must carry its settings' deep_link_return_url")


def check_service_urls(launch: Launch) -> None:
    """LaunchError("services") unless every service URL of the launch (AGS line items and line item, the NRPS
    memberships, the deep-linking return URL) is at one of its platform's registered origins: the tool sends the
    platform's access token, and a deep-linking answer, nowhere else."""
    urls = {
        "lineitem": (launch.ags or {}).get("lineitem"),
        "lineitems": (launch.ags or {}).get("lineitems"),
        "context_memberships_url": (launch.nrps or {}).get("context_memberships_url"),
        "deep_link_return_url": (launch.deep_linking or {}).get("deep_link_return_url"),
    }
    for name, url in urls.items():
        if url is not None and not on_platform(launch.platform, url):
            allowed = ", ".join(platform_origins(launch.platform))
            raise LaunchError(
                "services", f"the launch's {name} ({url[:200]}) is not at the platform's registered addresses "
                f"({allowed}); the server's admin registers another with --service-origin",
            )  # fmt: skip
