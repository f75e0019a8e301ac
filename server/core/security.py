"""Who may do what, and what the server answers to: job ownership, the instructor, host names, headers.

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
- **Host names** (`HostCheck`): a request whose Host header is not a name the server serves is
  refused (400), against DNS rebinding: the loopback names, the address it listens on, and
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
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPBearer
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.core.errors import ApiError, errors_response
from server.core.settings import MIN_TOKEN_LENGTH, STRONG_TOKEN, Settings, loopback_address, weak_token

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


def share_token(row: dict) -> str | None:
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

bearer = HTTPBearer(
    auto_error=False,
    scheme_name="token",
    description="A job's token (POST /api/jobs issues one when none is sent), or the instructor's "
    "(TRACER_INSTRUCTOR_TOKEN) for grading and every job.",
)


@dataclass(frozen=True)
class Caller:
    """Who asks: their token's hash (None without a token) and whether they are the instructor."""

    token: str | None
    owner: str | None
    instructor: bool

    def shares(self, row: dict) -> bool:
        """Does this caller hold the job's read-only share token?"""
        key = share_token(row)
        return bool(key and self.token and hmac.compare_digest(key.encode(), self.token.encode()))

    def owns(self, row: dict) -> bool:
        """May this caller see the job? The instructor sees every job; a student those of their token."""
        if self.instructor:
            return True
        owner = row.get("owner")
        return bool(owner and self.owner and hmac.compare_digest(owner, self.owner))


def unauthorized(message: str, error: str = "invalid_token") -> ApiError:
    header = f'Bearer realm="tracer", error="{error}"' if error else 'Bearer realm="tracer"'
    return ApiError(401, [{"path": "Authorization", "message": message}], headers={"WWW-Authenticate": header})


def bearer_token(request: Request) -> str | None:
    """The request's bearer token; None without an Authorization header; 401 for a malformed one."""
    header = request.headers.get("authorization")
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


async def get_caller(request: Request, _: Annotated[object, Depends(bearer)] = None) -> Caller:
    """The caller of a request (`_`: only so that /docs offers a field for the token). `async`: it reads nothing
    but the request (no trip through the thread pool, server/api/deps.py)."""
    token = bearer_token(request)
    settings: Settings = request.app.state.settings
    if token is not None:  # an address that sent too many refused tokens waits (server/core/clients.py)
        request.app.state.caps.auth_allowed(request.client.host if request.client else None)
    secret = instructor_token(settings)
    if secret is not None:
        instructor = token is not None and hmac.compare_digest(token.encode(), secret.encode())
    else:
        instructor = loopback_only(settings.host)  # one person on their own machine
    return Caller(token, token_hash(token) if token else None, instructor)


CallerDep = Annotated[Caller, Depends(get_caller)]


def require_instructor(caller: CallerDep, request: Request) -> Caller:
    """401 unless the caller is the instructor (403 on a server that has no instructor)."""
    if caller.instructor:
        return caller
    settings: Settings = request.app.state.settings
    if instructor_token(settings) is None:
        message = (
            f"this server listens on {settings.host}, not on loopback only, and has no instructor token: "
            "start it with TRACER_INSTRUCTOR_TOKEN set to grade"
        )
        raise ApiError(403, [{"path": "Authorization", "message": message}])
    if caller.token is None:
        raise unauthorized("this needs the instructor's token: send 'Authorization: Bearer <token>'", "")
    request.app.state.caps.auth_failed(request.client.host if request.client else None)  # counted per address
    raise unauthorized("this token is not the instructor's (TRACER_INSTRUCTOR_TOKEN)")


InstructorDep = Annotated[Caller, Depends(require_instructor)]


# -- start-up --------------------------------------------------------------------------------------


def start_up_warnings(settings: Settings) -> list[str]:
    """What an operator should know about how open this server is (logged at start-up)."""
    out = []
    if instructor_token(settings) is None and not loopback_only(settings.host):
        out.append(
            f"listening on {settings.host} (not loopback only) without TRACER_INSTRUCTOR_TOKEN: grading is "
            "refused and jobs without an owner (grading renders, older jobs) cannot be read; set it"
        )
    weak = weak_token(instructor_token(settings)) if instructor_token(settings) else None
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


class HostCheck:
    """ASGI middleware: 400 for a request whose Host header names a host the server does not serve."""

    def __init__(self, app: ASGIApp, served: frozenset[str] | None):
        self.app, self.served = app, served

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or self.served is None:
            await self.app(scope, receive, send)
            return
        header = next((v for k, v in scope.get("headers") or () if k == b"host"), None)
        name = host_name(header.decode("latin-1")) if header is not None else ""
        if not name or not host_allowed(name, self.served):
            shown = repr(header.decode("latin-1")[:100]) if header is not None else "none"
            message = (
                f"the Host header ({shown}) is not a name this server answers to; it serves "
                f"{', '.join(sorted(self.served))} (TRACER_ALLOWED_HOSTS adds names)"
            )
            await errors_response(400, [{"path": "Host", "message": message}])(scope, receive, send)
            return
        await self.app(scope, receive, send)


# -- other sites ---------------------------------------------------------------------------------

CROSS_SITE_PATHS = ("/lti/login", "/lti/launch")  # a learning platform posts here from its own site (LTI 1.3)
STATE_CHANGING = frozenset({"POST", "PUT", "PATCH", "DELETE"})
DEFAULT_PORTS = {"http": "80", "https": "443"}


def origin_of(scheme: str, host: str) -> str:
    """An origin as a browser writes it (`scheme://host[:port]`), in lower case and without the scheme's default
    port, so that `http://localhost:80` and `http://localhost` compare equal."""
    scheme, host = scheme.lower(), host.strip().lower()
    name, colon, port = host.rpartition(":") if not host.endswith("]") else (host, "", "")
    if colon and port == DEFAULT_PORTS.get(scheme):
        host = name
    return f"{scheme}://{host}"


class CrossSiteCheck:
    """ASGI middleware: 403 for a state-changing request (POST, PUT, PATCH, DELETE) that a page of another site
    sent: its `Sec-Fetch-Site` is `cross-site`, or its `Origin` is neither this server's own origin (the request's
    scheme and Host) nor a host the server serves. A browser sends these headers and a page cannot forge them; a
    client without them (curl, Python) passes. The paths of CROSS_SITE_PATHS are posted to from another site by
    design and pass."""

    def __init__(self, app: ASGIApp, served: frozenset[str] | None):
        self.app, self.served = app, served

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in STATE_CHANGING or _exempt(scope["path"]):
            await self.app(scope, receive, send)
            return
        headers = {k: v.decode("latin-1") for k, v in scope.get("headers") or () if k in (b"origin", b"host",
                   b"sec-fetch-site")}  # fmt: skip
        origin, site = headers.get(b"origin"), headers.get(b"sec-fetch-site", "").strip().lower()
        own = origin_of(scope.get("scheme", "http"), headers.get(b"host", ""))
        if site != "cross-site" and (origin is None or self._ours(origin, own)):
            await self.app(scope, receive, send)
            return
        shown = repr(origin[:100]) if origin is not None else "none"
        why = "Sec-Fetch-Site says cross-site" if site == "cross-site" else f"it is not this server's ({own})"
        message = (
            f"the request's Origin header ({shown}) is another site's ({why}): a page of another site may not "
            f"change anything here ({scope['method']} refused); send it from this server's own page, or without "
            "a browser"
        )
        await errors_response(403, [{"path": "Origin", "message": message}])(scope, receive, send)

    def _ours(self, origin: str, own: str) -> bool:
        scheme, sep, host = origin.strip().partition("://")
        if not sep or scheme.lower() not in DEFAULT_PORTS:
            return False  # "null" (a sandboxed page, a file), or no origin a browser writes
        if origin_of(scheme, host) == own:
            return True
        name = host_name(host)
        return bool(name) and self.served is not None and host_allowed(name, self.served)


def _exempt(path: str) -> bool:
    return path.rstrip("/") in CROSS_SITE_PATHS


# -- headers -------------------------------------------------------------------------------------

POLICY = (
    "default-src 'self'; img-src 'self' blob: data:; object-src 'none'; base-uri 'self'; form-action 'self'; "
    "frame-ancestors 'none'"
)
NO_STORE = (b"cache-control", b"no-store")  # every /api answer's
DOCS_PATHS = ("/docs", "/docs/oauth2-redirect")  # Swagger UI's pages: an inline script each, allowed by its hash
INLINE_SCRIPT = re.compile(rb"<script>(.*?)</script>", re.S)
HEADERS = [
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"same-origin"),
]


def docs_policy(html: bytes) -> str:
    """The policy of a Swagger UI page: its inline scripts by hash, and the inline styles its UI sets."""
    hashes = " ".join(
        f"'sha256-{base64.b64encode(hashlib.sha256(s).digest()).decode()}'" for s in INLINE_SCRIPT.findall(html)
    )
    return (
        f"default-src 'self'; script-src 'self' {hashes}; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
        "object-src 'none'; base-uri 'self'; form-action 'self'; frame-ancestors 'none'"
    )


FRAMED_PREFIXES = ("/lti/", "/assignments/", "/courses/")  # the pages an LMS may frame
FRAMED_PATHS = ("/", "/course")


def framed_policy(origins: list[str]) -> str:
    """POLICY for a page that the LTI platforms at `origins` may frame (and post forms to: a deep link's answer)."""
    allowed = " ".join(origins)
    return POLICY.replace("frame-ancestors 'none'", f"frame-ancestors 'self' {allowed}").replace(
        "form-action 'self'", f"form-action 'self' {allowed}"
    )


class SecurityHeaders:
    """ASGI middleware: every answer gets the content security policy and the headers above. `frame_ancestors`
    (optional): the origins that may frame the pages an LMS shows (LTI, server/lti/): when it names some, those
    pages get `frame-ancestors 'self' <origins>` and no X-Frame-Options."""

    def __init__(self, app: ASGIApp, frame_ancestors: Callable[[], list[str]] | None = None):
        self.app, self.frame_ancestors = app, frame_ancestors

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if scope["path"] in DOCS_PATHS:
            await self._docs(scope, receive, send)
            return
        path = scope["path"]
        may_frame = self.frame_ancestors and (path in FRAMED_PATHS or path.startswith(FRAMED_PREFIXES))

        api = scope["path"] == "/api" or scope["path"].startswith("/api/")

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                origins = self.frame_ancestors() if may_frame else []  # as they are when the answer starts
                policy = framed_policy(origins) if origins else POLICY
                headers = message.get("headers") or []
                if api:  # tokens, grades, students' work: never kept by a browser or a proxy
                    headers = [(k, v) for k, v in headers if k.lower() != b"cache-control"] + [NO_STORE]
                message["headers"] = _with(headers, policy, bool(origins))
            await send(message)

        await self.app(scope, receive, send_with_headers)

    async def _docs(self, scope: Scope, receive: Receive, send: Send) -> None:
        """A Swagger UI page is small: held whole, so that its policy can name its inline script's hash."""
        start, body = None, []

        async def held(message: Message) -> None:
            nonlocal start
            if message["type"] == "http.response.start":
                start = message
                return
            body.append(message.get("body", b""))
            if not message.get("more_body", False):
                html = b"".join(body)
                start["headers"] = _with(start.get("headers") or [], docs_policy(html))
                await send(start)
                await send({"type": "http.response.body", "body": html})

        await self.app(scope, receive, held)


def _with(headers, policy: str, framed: bool = False) -> list:
    have = {k.lower() for k, _ in headers} | ({b"x-frame-options"} if framed else set())
    out = list(headers) + [(k, v) for k, v in HEADERS if k not in have]
    if b"content-security-policy" not in have:
        out.append((b"content-security-policy", policy.encode()))
    return out
