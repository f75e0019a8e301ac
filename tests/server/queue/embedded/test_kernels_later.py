"""The page answers before the render kernels are loaded (issue #42: a warm `./dev serve` took 13-15 s on a loaded
machine, 7 s of it loading them before anything answered). `python -m server` loads them in a thread once it has
started, and starts its render workers once they are; meanwhile `/` and `/api/health` answer (health's status
"starting"), and a render submitted waits in the queue, then is done. The loading is made slow with
TRACER_KERNEL_LOAD_GATE (it waits for a file the test makes): the workers' start only, no request waits for it."""

from __future__ import annotations

from tests.support.api import Server, job, submit, tiny_scene, wait_finished, wait_for

READY = 120  # seconds: a bound on the workers' start once the gate is open, not a speed measurement


def test_the_page_answers_while_the_kernels_load_and_a_render_waits_for_them(tmp_path):
    gate = tmp_path / "kernels-may-load"
    server = Server(tmp_path / "data", workers=1, env={"TRACER_KERNEL_LOAD_GATE": str(gate)})
    server.start(workers_ready=False)  # as soon as /api/health answers
    try:
        http = server.client
        page = http.get("/")
        assert page.status_code == 200
        assert page.headers["content-type"].startswith("text/html")
        health = http.get("/api/health").json()
        assert health["status"] == "starting", health
        assert [(w["alive"], w["ready"]) for w in health["workers"]] == [(False, False)]  # not started yet
        assert "answering on http://127.0.0.1:" in server.log_text()
        assert "render kernels ready" not in server.log_text()

        queued = submit(http, tiny_scene())  # accepted, not refused: it waits for the worker
        assert job(http, queued["id"])["status"] == "queued"
        assert http.get("/api/health").json()["status"] == "starting"

        gate.touch()  # the kernels load, then the worker starts and takes the job
        assert wait_finished(http, queued["id"], timeout=READY)["status"] == "done"
        health = wait_for(lambda: (h := http.get("/api/health").json())["status"] == "ok" and h, READY, "health ok")
        assert [w["ready"] for w in health["workers"]] == [True]
        log = server.log_text()
        assert log.index("answering on http://127.0.0.1:") < log.index("render kernels ready")
    finally:
        server.__exit__()
