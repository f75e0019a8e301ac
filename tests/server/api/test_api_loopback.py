"""The service as users run it: `python -m server` on 127.0.0.1, driven over real HTTP.

A job's whole life against the CLI's pixels, a worker process killed mid-job, a server killed and
restarted with jobs queued and running, and 50 concurrent submissions.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
import threading
import zipfile
from concurrent.futures import ThreadPoolExecutor

import httpx
import numpy as np
import pytest

from tests.support.api import (
    Server,
    bearer,
    free_port,
    job,
    long_scene,
    parse_sse,
    pid_alive,
    student_token,
    submit,
    tiny_scene,
    wait_finished,
    wait_for,
    wait_status,
)
from tests.support.scene import ROOT
from tracer.rendering.film import read_exr


@pytest.fixture(scope="module")
def shared(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("loopback") / "data", workers=1) as s:
        yield s


@pytest.fixture
def server(shared):
    """The module's server; jobs a test leaves unfinished are cancelled after it, so none delays the next."""
    yield shared
    jobs = shared.client.get("/api/jobs", params={"limit": 1000}).json()["jobs"]
    for j in jobs:
        if not j["finished"]:
            shared.client.delete(f"/api/jobs/{j['id']}")
    wait_for(lambda: shared.client.get("/api/health").json()["jobs"]["running"] == 0, 120, "the worker to be idle")


def test_api_loopback_job_life_gives_the_cli_pixels(server, tmp_path):
    scene = tiny_scene(48, spp=16, seed=3)
    http = server.client
    created = submit(http, scene)
    events = []
    with http.stream("GET", created["events_url"], timeout=120) as r:
        assert r.headers["content-type"].startswith("text/event-stream")
        for event in parse_sse(r.iter_lines()):
            events.append(event)
            if event[0] == "preview":  # fetch each new preview while the job runs
                png = http.get(event[1]["url"])
                assert png.status_code == 200
                assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
    assert events[-1][0] == "end"
    assert events[-1][1]["status"] == "done"
    assert any(e == "progress" for e, _ in events)
    assert any(e == "preview" for e, _ in events)

    src = tmp_path / "scene.json"
    src.write_text(json.dumps(scene))
    cli = subprocess.run(
        [sys.executable, "-m", "tracer", "render", str(src), "-o", str(tmp_path / "cli.png"), "--exr",
         str(tmp_path / "cli.exr")],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert cli.returncode == 0, cli.stderr
    (tmp_path / "api.exr").write_bytes(http.get(f"/api/jobs/{created['id']}/image?format=exr").content)
    np.testing.assert_array_equal(read_exr(tmp_path / "api.exr"), read_exr(tmp_path / "cli.exr"))  # bit for bit
    from PIL import Image

    api_png = tmp_path / "api.png"
    api_png.write_bytes(http.get(f"/api/jobs/{created['id']}/image").content)
    np.testing.assert_array_equal(np.asarray(Image.open(api_png)), np.asarray(Image.open(tmp_path / "cli.png")))


def test_api_loopback_the_start_up_log_says_what_health_lists(server):
    """ "serving on ..." names as many render workers and checking processes as /api/health lists."""
    health = server.client.get("/api/health").json()
    line = next(x for x in server.log_path.read_text(errors="replace").splitlines() if "serving on" in x)
    workers, checkers = len(health["workers"]), len(health["checkers"])
    assert f"{workers} render worker process{'es' if workers != 1 else ''}, " in line, line
    assert f"{checkers} scene-checking processes" in line and "a grading pool of" in line, line


def test_api_loopback_nan_reaches_the_validator_which_names_its_field(server):
    body = b'{"scene": {"camera": {"lookfrom": [0, 0, NaN], "lookat": [0, 0, -1]}}}'
    r = server.client.post("/api/validate", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 200
    report = r.json()
    assert report["valid"] is False
    assert "camera.lookfrom[2]" in [e["path"] for e in report["errors"]]
    r = server.client.post("/api/jobs", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert [e["path"] for e in r.json()["errors"]] == ["camera.lookfrom[2]"]


def test_api_loopback_a_killed_worker_is_replaced_and_its_job_retried_then_failed(server):
    http = server.client
    created = submit(http, long_scene())
    wait_for(lambda: job(http, created["id"])["preview"] >= 1, 120, "the job to render")
    (pid,) = server.worker_pids()
    assert http.get("/api/health").json()["workers"][0]["job"] == created["id"]
    os.kill(pid, signal.SIGKILL)
    wait_for(lambda: not pid_alive(pid), 10, "the worker to die")
    assert http.get("/api/health").status_code == 200  # the API does not notice
    # the job goes back to the queue once and a new worker takes it
    retried = wait_for(
        lambda: (j := job(http, created["id"]))["attempts"] == 2 and j["status"] == "running" and j, 120, "a retry"
    )
    assert retried["error"] is None
    (second,) = wait_for(lambda: [p for p in server.worker_pids() if p != pid], 120, "a new worker")
    wait_for(lambda: job(http, created["id"])["preview"] >= 1, 120, "the retry to render")
    os.kill(second, signal.SIGKILL)  # killed again: out of tries
    failed = wait_finished(http, created["id"], timeout=120)
    assert failed["status"] == "failed"
    assert "render worker killed by signal SIGKILL" in failed["error"]
    assert "tried 2 time(s)" in failed["error"]
    wait_for(lambda: [p for p in server.worker_pids() if p not in (pid, second)], 120, "a third worker")
    # and the service goes on
    after = submit(http, tiny_scene())
    assert wait_finished(http, after["id"], timeout=120)["status"] == "done"


def test_api_loopback_cancel_running_then_queued(server):
    http = server.client
    running = submit(http, long_scene(), priority=50)
    waiting = submit(http, tiny_scene(), lane="batch")  # queued behind it (an interactive one: it would give way)
    wait_for(lambda: job(http, running["id"])["preview"] >= 1, 120, "the long job to render")
    assert job(http, waiting["id"])["status"] == "queued"
    r = http.delete(f"/api/jobs/{waiting['id']}")
    assert r.status_code == 200
    assert r.json()["status"] == "cancelled"
    with http.stream("GET", running["events_url"], timeout=120) as events:
        assert http.delete(f"/api/jobs/{running['id']}").status_code == 202
        last = list(parse_sse(events.iter_lines()))[-1]
    assert last[0] == "end"
    assert last[1]["status"] == "cancelled"
    assert last[1]["preview"] >= 1
    assert http.get(last[1]["image_url"]).status_code == 200  # the last image is kept


def test_api_loopback_a_stream_whose_client_left_is_followed_no_more(server):
    """An event stream does not ask whether its client left (500 streams asking once a second took a tenth of
    the event loop): the response notices the client's leaving and ends the stream. Health counts what follows
    a job; three streams of a long render closed by their clients leave nothing following it."""
    http = server.client
    running = submit(http, long_scene(), priority=50)
    with contextlib.ExitStack() as stack:
        readers = []  # kept: a reader dropped closes its stream
        for _ in range(3):
            client = stack.enter_context(httpx.Client(base_url=server.url, timeout=120, headers=http.headers))
            readers.append(parse_sse(stack.enter_context(client.stream("GET", running["events_url"])).iter_lines()))
            assert next(readers[-1])[0] == "progress"
        assert http.get("/api/health").json()["followers"] == 3
    wait_for(lambda: http.get("/api/health").json()["followers"] == 0, 30, "the closed streams to be followed no more")
    assert not job(http, running["id"])["finished"]  # ... while the job renders on, with changes to send


def test_api_loopback_50_concurrent_submissions_all_complete(server):
    def one(k: int) -> str:
        with httpx.Client(base_url=server.url, timeout=120) as c:
            return submit(c, tiny_scene(16, spp=1 if k % 2 else 4, seed=k), priority=k % 3)["id"]

    with ThreadPoolExecutor(50) as pool:
        ids = list(pool.map(one, range(50)))
    assert len(set(ids)) == 50

    def all_done():
        jobs = {j["id"]: j for j in server.client.get("/api/jobs", params={"limit": 1000}).json()["jobs"]}
        return all(jobs[i]["finished"] for i in ids) and jobs

    jobs = wait_for(all_done, 120, "50 jobs to finish", interval=0.2)
    assert {jobs[i]["status"] for i in ids} == {"done"}


def test_api_loopback_restart_loses_no_job(tmp_path):
    data = tmp_path / "data"
    with Server(data, workers=1) as first:
        http = first.client
        done = submit(http, tiny_scene(seed=1))
        wait_status(http, done["id"], {"done"}, timeout=120)
        png_before = http.get(f"/api/jobs/{done['id']}/image").content
        running = submit(http, long_scene(spp=256), priority=10)
        wait_for(lambda: job(http, running["id"])["preview"] >= 1, 120, "the long job to render")
        queued = [submit(http, tiny_scene(seed=k)) for k in range(4)]
        cancelled = submit(http, tiny_scene(seed=9))
        http.delete(f"/api/jobs/{cancelled['id']}")
        assert [job(http, q["id"])["status"] for q in queued] == ["queued"] * 4
        # a crash of the whole machine: the server and its worker die together, the job's row says running
        (worker,) = first.worker_pids()
        os.kill(worker, signal.SIGSTOP)
        first.stop(signal.SIGKILL)
        os.kill(worker, signal.SIGKILL)
        wait_for(lambda: not pid_alive(worker), 15, "the worker to die")

    with Server(data, workers=1) as second:
        http = second.client
        for j in [running, *queued]:
            assert wait_finished(http, j["id"], timeout=120)["status"] == "done"
        assert job(http, running["id"])["attempts"] == 2  # it was running: re-queued, rendered again
        assert job(http, cancelled["id"])["status"] == "cancelled"
        assert http.get(f"/api/jobs/{done['id']}/image").content == png_before  # finished images stay
        assert http.get("/api/jobs", params={"limit": 1000}).json()["count"] == 7


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["stopped", "killed"])
def test_api_loopback_a_stopped_server_s_worker_gives_its_job_back(tmp_path, sig):
    """SIGTERM: the server asks its worker to stop; SIGKILL: the orphaned worker sees its parent gone."""
    data = tmp_path / "data"
    with Server(data, workers=1) as first:
        running = submit(first.client, long_scene(spp=256))
        wait_for(lambda: job(first.client, running["id"])["status"] == "running", 120, "the job to start")
        (worker,) = first.worker_pids()
        first.stop(sig)
        wait_for(lambda: not pid_alive(worker), 60, "the worker to exit")
    with Server(data, workers=0) as second:
        back = job(second.client, running["id"])
        assert back["status"] == "queued"
        assert back["attempts"] == 0  # a stop is not the job's fault


def stopped_server_log(tmp_path, sig, work) -> str:
    """`python -m server` with one worker, `work(http)` done on it, then stopped by `sig`: everything the server,
    its worker, its grading processes and multiprocessing's resource tracker (which warns of leaked semaphores
    as it exits) wrote to the one pipe (stderr, with stdout). Reading it to its end waits for the last of them."""
    port = free_port()
    cmd = [sys.executable, "-m", "server", "--port", str(port), "--data-dir", str(tmp_path / "data"), "--workers", "1"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    reader.start()
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30, headers=bearer(student_token())) as http:

            def ready() -> bool:
                assert proc.poll() is None, "".join(lines)
                try:
                    workers = http.get("/api/health").json()["workers"]
                except httpx.TransportError:
                    return False
                return len(workers) == 2 and all(w["ready"] for w in workers)  # one, and one kept for the page

            wait_for(ready, 120, "the server to start", interval=0.2)
            work(http)
        proc.send_signal(sig)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    reader.join(timeout=60)
    assert not reader.is_alive(), "a process of the server still holds its output pipe"
    log = "".join(lines)
    assert "Application shutdown complete" in log
    assert "render workers stopped" in log
    return log


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_api_loopback_a_stopped_server_leaks_no_semaphore(tmp_path, sig):
    def render(http) -> None:  # a job rendered and its worker woken, as in real use
        created = submit(http, tiny_scene())
        assert wait_finished(http, created["id"], timeout=120)["status"] == "done"

    log = stopped_server_log(tmp_path, sig, render)
    assert "leaked semaphore" not in log, log[-3000:]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_api_loopback_a_server_stopped_after_grading_leaks_no_semaphore(tmp_path, sig):
    """A grading run's per-student work runs in a pool of processes (server/grading/pool.py), whose queues are
    five named semaphores: a stop after a grading run warned "There appear to be 5 leaked semaphore objects"
    (issue #42) as the pool was left without its queues closed."""
    example = ROOT / "scenes" / "grading"
    assignment = json.loads((example / "assignment.json").read_text())
    assignment["reference"]["scene"] = json.loads((example / "reference.json").read_text())
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.write(example / "class" / "alice.json", "hw/alice.json")

    def grade(http) -> None:
        r = http.post("/api/grade/upload", data={"assignment": json.dumps(assignment)},
                      files={"class": ("hw.zip", buf.getvalue(), "application/zip")})  # fmt: skip
        assert r.status_code == 202, r.text
        url = r.json()["url"]
        state = wait_for(lambda: (s := http.get(url).json())["status"] != "running" and s, 240, "the run", 0.2)
        assert state["status"] == "done" and state["graded"] == 1, state

    log = stopped_server_log(tmp_path, sig, grade)
    assert "leaked semaphore" not in log, log[-3000:]
