"""HTTP on loopback without a web framework, for the LTI platform an LMS plays (server/lti/platform.py): a plain
ASGI app over a table of routes (`routed_app`, each request a `Request` read whole, answered with an `Answer`), and
`LoopbackServer`, which runs any ASGI app with uvicorn on 127.0.0.1 in a thread (the tool's app too, in the tests);
it stops on leaving, also after a failure. Only server/api speaks HTTP through a framework; nothing here serves
beyond loopback.
"""

from __future__ import annotations

import asyncio
import json
import logging
import re
import socket
import threading
import time
from collections.abc import Callable
from urllib.parse import parse_qs

import uvicorn

log = logging.getLogger(__name__)

START_TIMEOUT = 30  # seconds a server may take to start (the tool's app loads its kernels from the cache)


class Request:
    """One HTTP request, read whole: method, path, query (each name's first value), headers (lower-case names)."""

    def __init__(self, scope: dict, body: bytes):
        self.method, self.path, self.body = scope["method"], scope["path"], body
        self.query_string = scope.get("query_string", b"").decode("latin-1")
        self.query = {k: v[0] for k, v in parse_qs(self.query_string).items()}
        self.headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        host = self.headers.get("host") or "{}:{}".format(*scope.get("server") or ("127.0.0.1", 80))
        self.url = f"{scope.get('scheme', 'http')}://{host}{self.path}" + (
            f"?{self.query_string}" if self.query_string else ""
        )

    def form(self) -> dict:
        """An application/x-www-form-urlencoded body (each name's first value)."""
        return {k: v[0] for k, v in parse_qs(self.body.decode(), keep_blank_values=True).items()}

    def json(self):
        return json.loads(self.body or b"null")


class Answer:
    """An HTTP answer: status, headers, body."""

    def __init__(self, status: int = 200, body: bytes = b"", media_type: str | None = None, headers=None):
        self.status, self.body = status, body
        self.headers = dict(headers or {})
        if media_type:
            self.headers["content-type"] = media_type

    def raw_headers(self) -> list[tuple[bytes, bytes]]:
        out = {"content-length": str(len(self.body)), **self.headers}
        return [(k.lower().encode("latin-1"), str(v).encode("latin-1")) for k, v in out.items()]

    @classmethod
    def json(cls, data, status: int = 200, media_type: str = "application/json", headers=None) -> Answer:
        return cls(status, json.dumps(data, separators=(",", ":")).encode(), media_type, headers)

    @classmethod
    def html(cls, text: str, status: int = 200) -> Answer:
        return cls(status, text.encode(), "text/html; charset=utf-8")

    @classmethod
    def redirect(cls, url: str) -> Answer:
        return cls(302, b"", None, {"location": url})


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LoopbackServer:
    """An ASGI app served by uvicorn on 127.0.0.1 (a free port) in a daemon thread; `url`; a context manager."""

    def __init__(self, app, port: int | None = None):
        self.app, self.port = app, port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        config = uvicorn.Config(app, host="127.0.0.1", port=self.port, log_level="warning", lifespan="on")
        self.server = uvicorn.Server(config)
        self.thread: threading.Thread | None = None

    def start(self) -> LoopbackServer:
        self.thread = threading.Thread(target=self.server.run, name=f"uvicorn-{self.port}", daemon=True)
        self.thread.start()
        deadline = time.monotonic() + START_TIMEOUT
        while not self.server.started:
            assert self.thread.is_alive(), f"the server on {self.url} stopped while starting"
            assert time.monotonic() < deadline, f"the server on {self.url} did not start in {START_TIMEOUT} s"
            time.sleep(0.05)
        return self

    def stop(self) -> None:
        if self.thread is not None:
            self.server.should_exit = True
            self.thread.join(timeout=30)
            self.thread = None

    def __enter__(self) -> LoopbackServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def routed_app(routes: list[tuple[str, re.Pattern, Callable]]):
    """`routes` (method, path pattern, handler) as a plain ASGI app (server/ speaks HTTP through a framework in
    server/api alone): each request read whole, answered by its route's handler in a thread (the platform's
    handlers fetch the tool's key set)."""

    async def app(scope, receive, send):
        if scope["type"] == "lifespan":
            while True:
                message = await receive()
                if message["type"] == "lifespan.startup":
                    await send({"type": "lifespan.startup.complete"})
                elif message["type"] == "lifespan.shutdown":
                    await send({"type": "lifespan.shutdown.complete"})
                    return
        if scope["type"] != "http":
            return
        body, more = b"", True
        while more:
            message = await receive()
            body += message.get("body", b"")
            more = message.get("more_body", False)
        req = Request(scope, body)
        found = [(m, p.match(req.path), h) for m, p, h in routes]
        matched = [(m, match, h) for m, match, h in found if match]
        handler = next(((match, h) for m, match, h in matched if m == req.method), None)
        if handler is None:
            answer = Answer.json({"error": "not found" if not matched else "method not allowed"},
                                 404 if not matched else 405)  # fmt: skip
        else:
            match, h = handler
            try:
                answer = await asyncio.to_thread(h, req, **match.groupdict())
            except Exception as e:  # noqa: BLE001 (a check that failed: the tool sees a 500, the test's log why)
                log.warning("test platform: %s %s failed: %r", req.method, req.path, e)
                answer = Answer.json({"error": f"{type(e).__name__}: {e}"}, 500)
        await send({"type": "http.response.start", "status": answer.status, "headers": answer.raw_headers()})
        await send({"type": "http.response.body", "body": answer.body})

    return app
