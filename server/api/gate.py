"""The request gate (`RequestGate`, ASGI middleware): body size and JSON depth, checked before any parser or
validator sees the body. It answers 413 past the body size limit (by Content-Length and by the bytes actually
streamed) and 400 for JSON nested deeper than the depth limit; an upload (a class's files) streams through it
with its own limit. A body must arrive in time (408), and the large bodies held at once, all requests together,
have a budget (`BodyBudget`: a request waits briefly for it, then gets 503 with Retry-After); a small body never
waits for it, so a student's small request passes a crowd of large ones.
"""

from __future__ import annotations

import asyncio
import re
import time

import anyio
from fastapi.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.api.errors import ApiError, errors_response
from server.core.jsondepth import json_depth
from server.core.settings import THREAD_FROM

MIN_BODY_RATE = 100_000  # bytes/s: past its first body_timeout seconds, a streamed body must average this


class BodyBudget:
    """Bytes of large request bodies held at once, all requests together (`budget`; 0: no budget). A body
    takes its share before it is read and gives it back when its request has been answered; one that
    cannot have it within `wait` seconds is refused. One body may always be held, whatever its size.
    Used on the event loop only."""

    def __init__(self, budget: int, wait: float):
        self.budget, self.wait, self.held = int(budget), float(wait), 0
        self._freed: list[asyncio.Event] = []

    async def take(self, size: int) -> bool:
        if not self.budget:
            return True
        deadline = time.monotonic() + self.wait
        while self.held and self.held + size > self.budget:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            freed = asyncio.Event()
            self._freed.append(freed)
            with anyio.move_on_after(left):
                await freed.wait()
        self.held += size
        return True

    def give_back(self, size: int) -> None:
        if not self.budget:
            return
        self.held -= size
        freed, self._freed = self._freed, []
        for event in freed:
            event.set()


class RequestGate:
    """ASGI middleware: 413 past `max_bytes`, 400 past `max_depth` levels of JSON nesting, 408 for a body
    that has not arrived `body_timeout` seconds after its headers, 503 (with Retry-After) when the large
    bodies held at once are over `budget` (a BodyBudget) for longer than its wait. A body of less than
    THREAD_FROM bytes never waits for the budget.

    `streamed` names routes whose bodies are not JSON and are read as a stream by the route itself
    (a class's upload), each with its own limit (bytes, and the settings that make it): their bodies
    pass through unbuffered, counted, and the request fails with 413 as soon as it is past the limit,
    or with 408 when it arrives slower than MIN_BODY_RATE on average after its first `body_timeout` s."""

    def __init__(
        self, app: ASGIApp, max_bytes: int, max_depth: int, streamed: dict[str, tuple[int, str]] | None = None,
        body_timeout: float = 30.0, budget: BodyBudget | None = None,
        larger: list[tuple[re.Pattern, int, str]] | None = None,
    ):  # fmt: skip
        self.app, self.max_bytes, self.max_depth = app, max_bytes, max_depth
        self.streamed = streamed or {}
        self.larger = larger or []  # JSON routes (a path pattern) with a limit of their own above max_bytes
        self.body_timeout, self.budget = body_timeout, budget or BodyBudget(0, 0)

    def _timed_out(self) -> JSONResponse:
        msg = f"the request body did not arrive within {self.body_timeout:g} s (TRACER_BODY_TIMEOUT)"
        return errors_response(408, [{"path": "", "message": msg}], {"Connection": "close"})

    def _busy(self) -> JSONResponse:
        msg = (
            "the server holds too many large request bodies at the moment (TRACER_BODY_BUDGET_BYTES); "
            "try again in a few seconds"
        )
        return errors_response(503, [{"path": "", "message": msg}], {"Retry-After": "2"})

    def _too_large(self, limit: int | None = None, name: str = "TRACER_MAX_BODY_BYTES") -> JSONResponse:
        msg = f"request body larger than {limit or self.max_bytes} bytes ({name})"
        return errors_response(413, [{"path": "", "message": msg}])

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in ("POST", "PUT", "PATCH"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length")
        limit, name = self.streamed.get(scope["path"], (self.max_bytes, "TRACER_MAX_BODY_BYTES"))
        for pattern, most, setting in self.larger:
            if pattern.fullmatch(scope["path"]):
                limit, name = most, setting
        if length is not None:
            try:
                declared = int(length)
            except ValueError:
                await errors_response(400, [{"path": "", "message": "invalid Content-Length"}])(scope, receive, send)
                return
            if declared > limit:
                await self._too_large(limit, name)(scope, receive, send)
                return
        if scope["path"] in self.streamed:
            await self.app(scope, _counted(receive, limit, name, self.body_timeout), send)
            return
        share = 0  # of the budget: a large declared body takes its size, one of unknown size the most a body may be
        if length is not None and declared >= THREAD_FROM:
            share = declared
            if not await self.budget.take(share):
                await self._busy()(scope, receive, send)
                return
        held = [share]  # the shares this request holds (a body of unknown size takes one as it grows)
        try:
            await self._gated(scope, receive, send, held, limit, name)
        finally:
            self.budget.give_back(sum(held))

    async def _gated(self, scope: Scope, receive: Receive, send: Send, held: list[int], limit: int, name: str) -> None:
        """Read the whole body (it is bounded, in size and in time), then check it and replay it to the app."""
        chunks, size = [], 0
        with anyio.move_on_after(self.body_timeout) as reading:
            while True:
                message = await receive()
                if message["type"] == "http.disconnect":
                    return
                chunk = message.get("body", b"")
                size += len(chunk)
                if size > limit:
                    await self._too_large(limit, name)(scope, receive, send)
                    return
                if size >= THREAD_FROM and not any(held):  # a large body of unknown size (chunked)
                    if not await self.budget.take(limit):
                        await self._busy()(scope, receive, send)
                        return
                    held.append(limit)
                chunks.append(chunk)
                if not message.get("more_body", False):
                    break
        if reading.cancelled_caught:
            await self._timed_out()(scope, receive, send)
            return
        body = b"".join(chunks)
        depth = json_depth(body) if size < THREAD_FROM else await anyio.to_thread.run_sync(json_depth, body)
        if depth > self.max_depth:
            msg = f"JSON nested {depth} levels deep; at most {self.max_depth} (TRACER_MAX_JSON_DEPTH)"
            await errors_response(400, [{"path": "", "message": msg}])(scope, receive, send)
            return
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


def _counted(receive: Receive, limit: int, name: str, body_timeout: float = 30.0) -> Receive:
    """`receive`, counting the body's bytes: past `limit` it raises ApiError(413) into the route reading it, and
    ApiError(408) once the body arrives slower than its deadline: `body_timeout` seconds from its start plus
    a second per MIN_BODY_RATE bytes received."""
    seen, start = 0, time.monotonic()

    async def counted() -> Message:
        nonlocal seen
        left = start + body_timeout + seen / MIN_BODY_RATE - time.monotonic()
        with anyio.move_on_after(max(0.0, left)) as waiting:
            message = await receive()
        if waiting.cancelled_caught:
            msg = f"the request body arrives too slowly (at most {body_timeout:g} s, TRACER_BODY_TIMEOUT, then "
            msg += f"{MIN_BODY_RATE} bytes per second)"
            raise ApiError(408, [{"path": "", "message": msg}], {"Connection": "close"})
        if message["type"] == "http.request":
            seen += len(message.get("body", b""))
            if seen > limit:
                raise ApiError(413, [{"path": "", "message": f"request body larger than {limit} bytes ({name})"}])
        return message

    return counted
