"""bench.burst's clients (issue #39, item 13): each one connects only after the barrier, so that no connection sits
idle while the other clients start (the server's header timeout closed 234 of 300 of them on a loaded machine)."""

from __future__ import annotations

import socket
import threading
import time

from bench.burst import Student


def test_a_burst_client_connects_after_the_barrier():
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    listener.settimeout(0)
    barrier = threading.Barrier(2)
    port = listener.getsockname()[1]
    student = Student(0, port, "a1", "tok", b"{}", "127.0.0.1", barrier, False, "submit")
    student.start()
    try:
        for _ in range(2000):  # the client waits at the barrier (bounded: 20 s)
            if barrier.n_waiting == 1:
                break
            time.sleep(0.01)
        assert barrier.n_waiting == 1
        time.sleep(0.2)  # a connection made before the barrier would be in the listener's backlog by now
        try:
            early = listener.accept()[0]
        except BlockingIOError:
            early = None
        assert early is None, "the client connected before the barrier"
        barrier.wait(timeout=20)
        listener.settimeout(20)
        conn, _ = listener.accept()
        with conn:
            conn.settimeout(20)
            request = b""
            while b"\r\n\r\n{}" not in request:
                chunk = conn.recv(4096)
                assert chunk, request
                request += chunk
            assert request.startswith(b"POST /api/assignments/a1/submissions "), request
            conn.sendall(b"HTTP/1.1 202 Accepted\r\nContent-Length: 2\r\nConnection: close\r\n\r\n{}")
        student.join(timeout=20)
        assert student.code == 202 and student.error is None, (student.code, student.error)
    finally:
        listener.close()
        student.join(timeout=20)
