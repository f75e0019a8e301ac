"""The middleware every request passes (server/main.py adds it), applying the rules of server/core/security.py:

- `HostCheck`: 400 for a Host header that names no host the server serves (against DNS rebinding);
- `CrossSiteCheck`: 403 for a state-changing request that a page of another site sent;
- `SecurityHeaders`: the content security policy, no sniffing, no framing (but of the pages an LMS shows, by the
  registered LTI platforms), and `Cache-Control: no-store` on every /api answer.
"""

from __future__ import annotations

import base64
import hashlib
import re
from collections.abc import Callable

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.api.errors import errors_response
from server.core.security import host_allowed, host_name


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
        framed = path in FRAMED_PATHS or path.startswith(FRAMED_PREFIXES)
        ancestors = self.frame_ancestors if framed else None

        api = scope["path"] == "/api" or scope["path"].startswith("/api/")

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                origins = ancestors() if ancestors else []  # as they are when the answer starts
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
                assert start is not None  # (ASGI: the start comes first)
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
