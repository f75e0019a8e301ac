"""Server-Sent Events, the one way a route answers with a stream (a job's events; a submission's as its grade
moves): `event_stream` takes room under the caller's caps of open streams (429 past them), frames the events
(the client's reconnection delay first) and gives the room back when the stream ends, however it ends.

An event is `sse(name, data)`: `event: <name>` and one line of compact JSON. A stream with nothing to say for a
while sends KEEP_ALIVE, a comment: a client or a proxy that waits for bytes keeps the connection open, and a
client that left is noticed at that write at the latest."""

from __future__ import annotations

import contextlib
import json
from collections.abc import AsyncGenerator, AsyncIterator, Callable

from fastapi import Request
from fastapi.responses import StreamingResponse

from server.core.security import Caller

RETRY = "retry: 1000\n\n"  # the client's wait before it reconnects, in ms: the first thing every stream says
KEEP_ALIVE = ": keep-alive\n\n"
HEADERS = {"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}  # no cache, no proxy's buffering (nginx)


def sse(event: str, data: dict) -> str:
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


class CappedStream(StreamingResponse):
    """An event stream that holds room under its client's caps of open streams (server/core/clients.py,
    `StreamCaps`) and gives it back when it ends, however it ends (finished, the client gone, the server
    stopping)."""

    def __init__(self, content, release: Callable[[], None], **kwargs):
        super().__init__(content, **kwargs)
        self.release = release

    async def __call__(self, scope, receive, send) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            self.release()


def stream_room(request: Request, caller: Caller) -> Callable[[], None]:
    """Room for one more open event stream of this caller (their token and their address); 429 past a cap. The
    instructor's streams are not counted. The answer gives it back: hand it to a `CappedStream`."""
    if caller.instructor:
        return lambda: None
    return request.app.state.streams.open(caller.owner, request.client.host if request.client else None)


async def _framed(events: AsyncGenerator[str, None]) -> AsyncIterator[str]:
    async with contextlib.aclosing(events):  # closed with the stream: its followers end with it, not at collection
        yield RETRY
        async for text in events:
            yield text


def event_stream(request: Request, caller: Caller, events: AsyncGenerator[str, None]) -> CappedStream:
    """The answer that streams `events` (texts of `sse` and KEEP_ALIVE), under the caller's caps of open streams
    (429 past them, before anything is sent)."""
    release = stream_room(request, caller)
    return CappedStream(_framed(events), release, media_type="text/event-stream", headers=HEADERS)
