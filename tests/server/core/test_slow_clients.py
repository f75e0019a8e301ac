"""Slow clients and bodies in flight (issue #24, item 5), against `python -m server` on loopback over raw
sockets: connections whose headers or bodies never finish are closed (a 408 when a request was begun),
and the large bodies held at once have a budget (503 with Retry-After past it) that a small request
never waits for.

The sockets' timeouts bound how long the test waits for an end that must come; they are not speed
measurements (each deadline here is 1 or 2 s, the bound 30 s)."""

from __future__ import annotations

import json
import socket
from contextlib import ExitStack

from tests.support.api import Server, tiny_scene

BOUND = 30  # seconds a socket waits for the server's answer or its end of the connection
HEAD = "POST /api/validate HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"


def connect(server: Server, stack: ExitStack) -> socket.socket:
    s = stack.enter_context(socket.create_connection(("127.0.0.1", server.port)))
    s.settimeout(BOUND)
    return s


def until_closed(s: socket.socket) -> bytes:
    """Everything the server sends until it closes the connection (socket.timeout if it never does)."""
    out = b""
    while chunk := s.recv(65536):
        out += chunk
    return out


def answer(s: socket.socket) -> tuple[int, dict, bytes]:
    """One HTTP answer: (status, headers, body), read up to its Content-Length."""
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = s.recv(65536)
        assert chunk, f"closed without an answer: {data!r}"
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    headers = dict(line.lower().split(": ", 1) for line in lines[1:])
    while len(body) < int(headers.get("content-length", 0)):
        body += s.recv(65536)
    return int(lines[0].split()[1]), headers, body


def test_slow_clients_headers_and_bodies_that_never_end_are_closed(tmp_path):
    env = {"TRACER_HEADER_TIMEOUT": "1", "TRACER_BODY_TIMEOUT": "2"}
    with Server(tmp_path / "data", workers=0, env=env) as server, ExitStack() as stack:
        silent = [connect(server, stack) for _ in range(3)]  # connected, and not a byte since
        headers = [connect(server, stack) for _ in range(5)]
        for s in headers:
            s.sendall(HEAD.encode())  # the headers' blank line never comes
        bodies = [connect(server, stack) for _ in range(5)]
        for s in bodies:
            s.sendall(f"{HEAD}Content-Length: 1000\r\n\r\n".encode() + b"{" + b" " * 998)  # one byte short
        idle = connect(server, stack)  # a keep-alive connection after an answer, then silent
        idle.sendall(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        assert answer(idle)[0] == 200
        for s in silent:
            assert until_closed(s) == b""
        for s in headers:
            assert until_closed(s).startswith(b"HTTP/1.1 408 ")
        for s in bodies:
            status, _, body = answer(s)
            assert status == 408, body
            until_closed(s)
        assert until_closed(idle) == b""
        r = server.client.post("/api/validate", json={"scene": tiny_scene()})  # and the server serves on
        assert r.status_code == 200
        assert r.json()["valid"] is True


def test_slow_clients_large_bodies_share_a_budget_that_small_ones_pass(tmp_path):
    """A budget of 300 kB for large bodies (64 KB or more), and half a second's wait for it: while one
    client's 200 kB body is held (stalled half way), another's is answered 503 with Retry-After; a small
    request is served meanwhile; once the first body is complete and answered, a large one is taken again,
    and so is one after a chunked body (of unknown size) was answered."""
    env = {"TRACER_BODY_BUDGET_BYTES": "300000", "TRACER_BODY_BUDGET_WAIT": "0.5", "TRACER_BODY_TIMEOUT": "60"}
    pad = "x" * 200_000
    body = json.dumps({"scene": tiny_scene(), "pad": pad}).encode()
    request = f"{HEAD}Content-Length: {len(body)}\r\n\r\n".encode()
    with Server(tmp_path / "data", workers=0, env=env) as server, ExitStack() as stack:
        held = connect(server, stack)
        held.sendall(request + body[: len(body) // 2])
        small = server.client.post("/api/validate", json={"scene": tiny_scene()})
        assert small.status_code == 200
        assert small.json()["valid"] is True
        refused = connect(server, stack)
        refused.sendall(request)
        status, headers, text = answer(refused)
        assert status == 503 and headers["retry-after"] == "2", text
        assert "TRACER_BODY_BUDGET_BYTES" in json.loads(text)["errors"][0]["message"]
        held.sendall(body[len(body) // 2 :])
        assert answer(held)[0] == 422  # its `pad` is no field of the request: answered, and its share given back
        again = connect(server, stack)
        again.sendall(request + body)
        assert answer(again)[0] == 422
        chunked = connect(server, stack)  # of unknown size: it takes the most a body may be, and gives it back
        chunks = b"".join(
            b"%x\r\n%s\r\n" % (len(body[k : k + 50_000]), body[k : k + 50_000]) for k in range(0, len(body), 50_000)
        )
        chunked.sendall(f"{HEAD}Transfer-Encoding: chunked\r\n\r\n".encode() + chunks + b"0\r\n\r\n")
        assert answer(chunked)[0] == 422
        last = connect(server, stack)
        last.sendall(request + body)
        assert answer(last)[0] == 422
