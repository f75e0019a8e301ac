"""Who may do what, and what the server answers to: job ownership, the instructor, host names, headers. The rules
are here, free of HTTP; the routes' dependencies (server/api/deps.py) and the middleware that enforces the host,
cross-site and header rules on every request (server/api/middleware.py) apply them.

- **Jobs belong to a token.** POST /api/jobs takes `Authorization: Bearer <token>`; without one it
  issues a fresh random token (`secrets.token_urlsafe(32)`) in the answer's `token`. The store keeps
  only the token's SHA-256 (the jobs' `owner` column). A job is read, streamed, cancelled or
  downloaded only with the token that made it (or the instructor's); any other caller gets the 404 of an
  unknown id, so ids are not confirmed. That holds where there is an instructor to tell apart: with
  TRACER_INSTRUCTOR_TOKEN, or off loopback; on a loopback-only server without it everyone is the instructor.
  A job with no owner (the server's grading renders, rows from before owners) is the instructor's; a ray
  tree asked for without a token belongs to its client's address (server/core/clients.py, which also caps
  what one address may do without a known identity).
- **A read-only share token** of a job (POST /api/jobs/{id}/share, its owner only) reads that one job: its
  GET routes (the job, its events, image, AOVs, scene, radiosity), never a cancel, never another job. It is
  an HMAC of the job's id keyed by the owner's token hash, so the server keeps nothing more, it cannot be
  turned back into the owner's token, and it dies with the job.
- **The instructor** (TRACER_INSTRUCTOR_TOKEN) grades, lists every job and reads any. Without such a
  token, a server that listens on loopback only is one person's own machine and everyone is the
  instructor (everything works as before tokens); a server on another address then has no instructor
  (grading is refused with 403), and warns at start-up.
- **Host names** (`HostCheck`, server/api/middleware.py): a request whose Host header is not a name the server
  serves is refused (400), against DNS rebinding: the loopback names, the address it listens on, and
  TRACER_ALLOWED_HOSTS. A Host is a name or a bracketed IPv6 literal, then at most a port of digits in
  1..65535 (`host_name`): anything else names no host. A server listening on every address (0.0.0.0, ::)
  with no list accepts any Host, and warns at start-up.
- **Other sites** (`CrossSiteCheck`): a state-changing request (POST, PUT, PATCH, DELETE) that a page of another
  site sent (`Sec-Fetch-Site: cross-site`, or an `Origin` that is neither the server's own, the request's scheme
  and Host, nor a served host) is refused (403), on every server: without it, a page anyone opens could publish an
  assignment on a loopback server that has no instructor token. Clients that send neither header (curl, Python)
  pass; CROSS_SITE_PATHS (LTI's login and launch, which a learning platform posts from its own site) pass.
- **Headers** (`SecurityHeaders`): a content security policy that lets the page load only its own
  assets (and /docs its one inline script, by hash), no MIME sniffing, no framing (but of the pages an LMS
  shows, by the registered LTI platforms: `frame_ancestors`), no referrer to other sites; and
  `Cache-Control: no-store` on every /api answer (tokens, grades, students' work: none is kept by a browser's
  cache or a proxy), whatever the route said.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import ipaddress
import logging
import re
import secrets
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from server.core.credentials import MIN_TOKEN_LENGTH, STRONG_TOKEN, loopback_address, weak_token
from server.core.errors import Forbidden, Unauthorized
from server.core.settings import Settings

log = logging.getLogger("server")

TOKEN = re.compile(r"[A-Za-z0-9._~+/=-]{16,512}")  # RFC 6750's b64token, 16 to 512 characters
TOKEN_WORDS = "16 to 512 letters, digits or -._~+/="
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
WILDCARDS = ("0.0.0.0", "::", "")  # listening on every address


def new_token() -> str:
    return secrets.token_urlsafe(32)  # 256 random bits


def token_hash(token: str) -> str:
    """What the store keeps of a token: its SHA-256, in hex."""
    return hashlib.sha256(token.encode()).hexdigest()


def share_token(row: Mapping[str, Any]) -> str | None:
    """The job's read-only share token (None for a job with no owner: the instructor's own)."""
    owner = row.get("owner")
    if not owner:
        return None
    digest = hmac.new(bytes.fromhex(owner), f"share:{row['id']}".encode(), hashlib.sha256).digest()
    return "share-" + base64.urlsafe_b64encode(digest).decode().rstrip("=")


def loopback_only(host: str) -> bool:
    """Does an address to listen on (python -m server --host) reach this machine only?"""
    return loopback_address(host)


def instructor_token(settings: Settings) -> str | None:
    return settings.instructor_token.get_secret_value() if settings.instructor_token else None


# -- the caller ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Caller:
    """Who asks: their token's hash (None without a token) and whether they are the instructor."""

    token: str | None
    owner: str | None
    instructor: bool

    def shares(self, row: Mapping[str, Any]) -> bool:
        """Does this caller hold the job's read-only share token?"""
        key = share_token(row)
        return bool(key and self.token and hmac.compare_digest(key.encode(), self.token.encode()))

    def owns(self, row: Mapping[str, Any]) -> bool:
        """May this caller see the job? The instructor sees every job; a student those of their token."""
        if self.instructor:
            return True
        owner = row.get("owner")
        return bool(owner and self.owner and hmac.compare_digest(owner, self.owner))


def unauthorized(message: str, error: str = "invalid_token") -> Unauthorized:
    """A 401 at the Authorization header; `error` the bearer challenge's error code ("" for none)."""
    return Unauthorized.at("Authorization", message, challenge=error)


def parse_bearer(header: str | None) -> str | None:
    """The bearer token of an Authorization header; None without the header; 401 for a malformed one."""
    if header is None:
        return None
    scheme, _, value = header.strip().partition(" ")
    value = value.strip()
    if scheme.lower() != "bearer" or not TOKEN.fullmatch(value):
        raise unauthorized(
            f"expected the header 'Authorization: Bearer <token>' with a token of {TOKEN_WORDS} "
            "(the token POST /api/jobs gave, or the instructor's)",
            "invalid_request",
        )
    return value


def is_instructor(token: str | None, settings: Settings) -> bool:
    """Is the bearer of `token` the instructor? Without TRACER_INSTRUCTOR_TOKEN, everyone is on a loopback-only
    server (one person on their own machine) and nobody is on any other."""
    secret = instructor_token(settings)
    if secret is not None:
        return token is not None and hmac.compare_digest(token.encode(), secret.encode())
    return loopback_only(settings.host)


def check_instructor(caller: Caller, settings: Settings, refused: Callable[[], None] = lambda: None) -> Caller:
    """The caller, if they are the instructor; else 403 on a server that has no instructor, 401 otherwise.
    `refused()` is told of a token that was not the instructor's (counted against its address:
    server/core/clients.py)."""
    if caller.instructor:
        return caller
    if instructor_token(settings) is None:
        message = (
            f"this server listens on {settings.host}, not on loopback only, and has no instructor token: "
            "start it with TRACER_INSTRUCTOR_TOKEN set to grade"
        )
        raise Forbidden.at("Authorization", message)
    if caller.token is None:
        raise unauthorized("this needs the instructor's token: send 'Authorization: Bearer <token>'", "")
    refused()
    raise unauthorized("this token is not the instructor's (TRACER_INSTRUCTOR_TOKEN)")


# -- start-up --------------------------------------------------------------------------------------


def start_up_warnings(settings: Settings) -> list[str]:
    """What an operator should know about how open this server is (logged at start-up)."""
    out = []
    if instructor_token(settings) is None and not loopback_only(settings.host):
        out.append(
            f"listening on {settings.host} (not loopback only) without TRACER_INSTRUCTOR_TOKEN: grading is "
            "refused and jobs without an owner (grading renders, older jobs) cannot be read; set it"
        )
    token = instructor_token(settings)
    weak = weak_token(token) if token else None
    if weak:  # (refused at start on any other address: server/core/settings.py)
        out.append(
            f"TRACER_INSTRUCTOR_TOKEN is weak ({weak}): it is accepted on loopback only; use at least "
            f"{MIN_TOKEN_LENGTH} random characters before the server listens on another address ({STRONG_TOKEN})"
        )
    if served_hosts(settings) is None and not settings.allowed_hosts.strip():
        out.append(
            f"listening on every address ({settings.host or '*'}) without TRACER_ALLOWED_HOSTS: any Host header "
            "is accepted; name the server's host names in TRACER_ALLOWED_HOSTS"
        )
    return out


# -- host names ----------------------------------------------------------------------------------


def served_hosts(settings: Settings) -> frozenset[str] | None:
    """The host names a request may name (lower case, no port): the loopback names, the address the server
    listens on when it is one address, and TRACER_ALLOWED_HOSTS ('.example.edu' also names its
    subdomains). None: any (TRACER_ALLOWED_HOSTS=*, or listening on every address with no list)."""
    listed = [h.strip().lower().rstrip(".") for h in settings.allowed_hosts.split(",") if h.strip()]
    if "*" in listed:
        return None
    bound = settings.host.strip().strip("[]").lower().rstrip(".")
    if bound in WILDCARDS and not listed:
        return None
    names = {*LOOPBACK_NAMES, *listed}
    if bound not in WILDCARDS:
        names.add(bound)
    return frozenset(n.strip("[]") for n in names)


HOST_NAME = re.compile(r"[a-z0-9_-]+(?:\.[a-z0-9_-]+)*\.?")  # a DNS name or an IPv4 address, a final dot allowed
HOST_PORT = re.compile(r":([0-9]{1,5})")


def host_name(header: str) -> str:
    """A Host header's name: without its port, IPv6 brackets or a final dot, in lower case; "" (served by no
    server) unless the header is a name (letters, digits, '-', '_' and dots) or a bracketed IPv6 literal, then
    nothing but an optional port of digits in 1..65535 (RFC 9110's `uri-host [":" port]`, narrowed):
    `127.0.0.1:80@evil.com`, `[::1]x`, `localhost:0` and `host:` name nothing."""
    header = header.strip().lower()
    if header.startswith("["):
        name, bracket, rest = header[1:].partition("]")
        try:
            ipaddress.IPv6Address(name)
        except ValueError:
            return ""
        if not bracket:
            return ""
    else:
        name, colon, port = header.partition(":")
        rest = colon + port
        if not HOST_NAME.fullmatch(name):
            return ""
        name = name.rstrip(".")
    port = HOST_PORT.fullmatch(rest)
    if rest and not (port and 1 <= int(port[1]) <= 65535):
        return ""
    return name


def host_allowed(name: str, served: frozenset[str]) -> bool:
    return name in served or any(s.startswith(".") and (name == s[1:] or name.endswith(s)) for s in served)
