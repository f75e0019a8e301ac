"""A class at once on the default settings (issue #32, item 9): 300 students each render their scene in the
workspace in the same instant (POST /api/jobs, without a token, as the page's first render) and have it
validated as they type (POST /api/validate), each from a loopback address of their own as a class on a campus
network reaches the server. Every one of the 600 requests is accepted: the scene-checking line
(TRACER_MAX_VALIDATE_WAITING, _BYTES), the queue (TRACER_MAX_QUEUED_JOBS) and the per-address caps hold a class
of 300 (docs/service.md, "Sizing"; bench/burst.py measures the same with the numbers there). What is asserted is
the answers, not how long they took."""

from __future__ import annotations

import http.client
import json
import threading

from tests.support.api import Server
from tests.support.scene import scene_dict, small

STUDENTS = 300


def address(k: int) -> str:
    return f"127.0.{1 + k // 250}.{1 + k % 250}"


def test_burst_a_class_of_300_at_once_on_the_default_settings_is_never_refused(tmp_path):
    scene = small(scene_dict("whitted"), 48, 36)
    bodies = []
    for k in range(STUDENTS):
        s = dict(scene, name=f"student {k}", render={"seed": k})
        bodies.append(("/api/jobs", json.dumps({"scene": s}).encode()))
        bodies.append(("/api/validate", json.dumps({"scene": s}).encode()))
    answers: list[tuple[int, bytes] | str] = [""] * len(bodies)
    barrier = threading.Barrier(len(bodies) + 1)

    def client(i: int, port: int) -> None:
        path, body = bodies[i]
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120, source_address=(address(i // 2), 0))
        try:
            barrier.wait(timeout=60)
            conn.connect()  # after the barrier: a connection idle while the others start may meet the header timeout
            conn.request("POST", path, body=body, headers={"Content-Type": "application/json"})
            r = conn.getresponse()
            answers[i] = (r.status, r.read())
        except (OSError, http.client.HTTPException, threading.BrokenBarrierError) as e:
            answers[i] = f"{type(e).__name__}: {e}"
        finally:
            conn.close()

    with Server(tmp_path / "data", workers=1) as server:
        threading.stack_size(512 * 1024)
        threads = [threading.Thread(target=client, args=(i, server.port), daemon=True) for i in range(len(bodies))]
        for t in threads:
            t.start()
        barrier.wait(timeout=60)
        for t in threads:
            t.join(timeout=180)
        assert not any(t.is_alive() for t in threads), "a client still waits for its answer after 3 minutes"
    refused = [(bodies[i][0], a if isinstance(a, str) else (a[0], a[1][:200])) for i, a in enumerate(answers)
               if isinstance(a, str) or a[0] != (202 if bodies[i][0] == "/api/jobs" else 200)]  # fmt: skip
    assert not refused, f"{len(refused)} of {len(bodies)} refused, e.g. {refused[:3]}"
    tokens = {json.loads(a[1])["token"] for i, a in enumerate(answers) if bodies[i][0] == "/api/jobs"}
    assert len(tokens) == STUDENTS  # each student got a token of their own
    assert all(json.loads(a[1])["valid"] for i, a in enumerate(answers) if bodies[i][0] == "/api/validate")
