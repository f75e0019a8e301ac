"""bench.burst's clients (issue #39, item 13): each one connects only after the barrier, so that no connection sits
idle while the other clients start (the server's header timeout closed 234 of 300 of them on a loaded machine)."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import threading
import time

from bench.burst import Student, summary
from tests.support.scene import ROOT


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


def test_a_burst_prints_a_table_unless_json(tmp_path):
    """Issue #42: bench.burst printed only JSON. A real burst of 4 (a server of its own, on a free port): the table
    says what was accepted, the submit latency and when the class had its grades; no JSON on stdout."""
    done = subprocess.run(
        [sys.executable, "-m", "bench.burst", "--students", "4", "--follow"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    rows = dict(re.split(r"\s{2,}", line, maxsplit=1) for line in done.stdout.splitlines()[1:])
    assert rows["accepted"] == "4 of 4", done.stdout
    assert re.fullmatch(r"\d+\.\d\d / \d+\.\d\d s", rows["submit p50 / p99"]), done.stdout
    assert re.fullmatch(r"p50 [\d.]+ s, p99 [\d.]+ s, last [\d.]+ s \(3 graded, 1 invalid\)", rows["graded within"])
    assert "{" not in done.stdout


def test_a_burst_s_table_names_each_refusal_by_its_status():
    result = {
        "students": 300, "what": "render", "backend": "embedded", "addresses": "own",
        "codes": {"202": 212, "429": 42, "None": 1, "503": 45}, "errors": {"ConnectionResetError": 1},
        "submit_latency_s": {"n": 254, "p50": 0.514, "p90": 0.7, "p99": 0.871, "max": 0.9, "mean": 0.5},
        "feedback_s": None, "statuses": {}, "took_s": 4.2, "load_before": ["0.4"] * 3, "load_after": ["1.0"] * 3,
    }  # fmt: skip
    rows = dict(re.split(r"\s{2,}", line, maxsplit=1) for line in summary(result).splitlines())
    assert rows["accepted"] == "212 of 300"
    assert (rows["refused 429"], rows["refused 503"], rows["refused none"]) == ("42", "45", "1")
    assert rows["submit p50 / p99"] == "0.51 / 0.87 s"
    assert rows["error"] == "1 x ConnectionResetError"
    assert "graded within" not in rows
