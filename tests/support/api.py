"""Helpers of the API tests (their own tests are tests/test_support_api.py): scenes, the app in a TestClient (the
fixtures `client`, `client_without_workers` and `settings` of tests/conftest.py are built with `api_client`), jobs
through it, Server-Sent Events, and a real server on loopback."""

from __future__ import annotations

import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

import httpx
import numpy as np

from tests.support import zygote
from tests.support.scene import ROOT, scene_dict, small

SERVER_START_TIMEOUT = 120  # seconds: the first start may compile the kernels
INSTRUCTOR = "instructor-token-of-the-tests"  # TRACER_INSTRUCTOR_TOKEN where a test's server has one


def student_token() -> str:
    """A fresh token, as POST /api/jobs issues them."""
    return secrets.token_urlsafe(32)


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def tiny_scene(size: int = 16, spp: int = 4, seed: int = 0) -> dict:
    """Whitted's scene at a few pixels: renders in milliseconds."""
    return small(scene_dict("whitted"), size, size, sampler={"type": "jittered", "spp": spp}, render={"seed": seed})


def long_scene(spp: int = 1024) -> dict:
    """Whitted's scene at 192 x 144 with many samples: several seconds per pass late in the render."""
    return small(scene_dict("whitted"), 192, 144, sampler={"type": "jittered", "spp": spp})


def wait_for(condition: Callable[[], object], timeout: float, what: str, interval: float = 0.05):
    """Poll `condition` until it returns something true; fail with `what` after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out after {timeout} s waiting for {what}"
        time.sleep(interval)


# -- the app in a TestClient, and jobs through it ------------------------------------------------

WORKERS_READY_TIMEOUT = 60  # seconds: a worker loads the kernels from Warp's cache


@contextmanager
def api_client(
    data_dir: Path, workers: int = 0, raise_server_exceptions: bool = True, token: str | None = "", **settings
) -> Iterator:
    """A TestClient of the app on `data_dir` with `settings`, its lifespan run (kernels, job store,
    `workers` render processes, janitor), once its workers are ready; stopped on leaving. No worker kept
    for interactive work unless `interactive_workers` says so (the lanes' own tests do). The client asks
    for http://127.0.0.1 (a Host the server serves) and sends `Authorization: Bearer <token>` on every
    request: a fresh student's token unless given (None: no header)."""
    from fastapi.testclient import TestClient

    from server.core.settings import Settings
    from server.main import create_app

    settings.setdefault("interactive_workers", 0)
    settings.setdefault("previews_ahead", False)  # no example previews queued behind the test's own jobs
    settings.setdefault("answer_again", False)  # each job rendered (tests of the answers again turn it on)
    settings.setdefault("lessons_ahead", False)  # no lesson panels queued behind the test's own jobs
    settings.setdefault("max_auth_failures", 100_000)  # the tests' refused tokens, one address: tested on its own
    app = create_app(Settings(data_dir=data_dir, workers=workers, **settings))
    every = workers + settings["interactive_workers"] if workers else 0
    token = student_token() if token == "" else token
    headers = bearer(token) if token else {}
    base = "http://127.0.0.1"
    with TestClient(app, base_url=base, raise_server_exceptions=raise_server_exceptions, headers=headers) as client:

        def ready() -> bool:
            return [w["ready"] for w in client.get("/api/health").json()["workers"]] == [True] * every

        wait_for(ready, WORKERS_READY_TIMEOUT, "the render workers")
        yield client


class Clock:
    """A clock the test sets (`now`: a datetime for the app's clock, seconds for a component's own)."""

    def __init__(self, now):
        self.now = now

    def __call__(self):
        return self.now


@contextmanager
def course_client(data_dir: Path, now: datetime, workers: int = 1, **settings) -> Iterator:
    """`api_client` as the instructor with `workers` render workers, its app's clock a `Clock` at `now` (the course's
    deadlines, caps and feedback times follow it): `client.app.state.clock.now = ...` moves it."""
    with api_client(data_dir, workers, instructor_token=INSTRUCTOR, token=INSTRUCTOR, **settings) as client:
        client.app.state.clock = Clock(now)
        yield client


def submit(client, scene: dict, priority: int = 0, lane: str | None = None) -> dict:
    """POST the scene as a job (202 expected); the job. `lane="batch"` moves it down to the batch lane (anyone
    may): a small job there never makes a running batch render give way to it."""
    body = {"scene": scene, "priority": priority} | ({"lane": lane} if lane else {})
    r = client.post("/api/jobs", json=body)
    assert r.status_code == 202, r.text
    assert r.headers["location"] == f"/api/jobs/{r.json()['id']}"
    return r.json()


def job(client, job_id: str) -> dict:
    r = client.get(f"/api/jobs/{job_id}")
    assert r.status_code == 200, r.text
    return r.json()


def wait_status(client, job_id: str, statuses: set[str], timeout: float = 60) -> dict:
    """The job, once its status is one of `statuses`; a job that ended in another fails at once (a status it
    passed through between two polls will not come back)."""
    j = wait_for(
        lambda: ((j := job(client, job_id))["status"] in statuses or j["finished"]) and j, timeout, f"job in {statuses}"
    )
    assert j["status"] in statuses, f"job {job_id} ended ({j['status']}) before it was seen in {statuses}: {j}"
    return j


def wait_finished(client, job_id: str, timeout: float = 60) -> dict:
    """The job, once it has ended (done, failed or cancelled: its `finished` flag)."""
    return wait_for(lambda: (j := job(client, job_id))["finished"] and j, timeout, f"job {job_id} to end")


def exr_of(client, job_id: str) -> np.ndarray:
    """The job's latest image as linear floats, through GET .../image?format=exr."""
    from tracer.rendering.film import read_exr

    r = client.get(f"/api/jobs/{job_id}/image", params={"format": "exr"})
    assert r.status_code == 200
    assert r.headers["content-type"] == "image/x-exr"
    path = client.app.state.settings.data_dir / f"check-{job_id}.exr"
    path.write_bytes(r.content)
    return read_exr(path)


# -- Server-Sent Events ---------------------------------------------------------------------------


def parse_sse(lines: Iterable[str]) -> Iterator[tuple[str, dict]]:
    """(event, data) pairs from the lines of a text/event-stream (comments and retry skipped)."""
    event, data = "message", []
    for line in lines:
        if line == "":
            if data:
                yield event, json.loads("\n".join(data))
            event, data = "message", []
        elif line.startswith(":"):
            continue
        else:
            field, _, value = line.partition(":")
            value = value[1:] if value.startswith(" ") else value
            if field == "event":
                event = value
            elif field == "data":
                data.append(value)


# -- a real server on loopback --------------------------------------------------------------------


def run_solutions(tmp_path_factory) -> dict[str, str]:
    """TRACER_CACHE_DIR for a server of the page's tests (and the previews' test): a radiosity solution cache shared
    by the run's servers that ask for it (each pytest process's base folder is under the run's one). The examples'
    two radiosity scenes are solved once in a run instead of once by each such server (about 10 s of CPU each time,
    their previews); the solutions are the same bits (a cache's key is all the solve depends on,
    tracer/radiosity/cache.py).
    Only for servers whose tests ask nothing of a solve itself: where a solve is fresh, what it reports, is tested
    with a server's own cache (tests/server/api/test_api_aov.py, test_queue_redis.py)."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    folder = base / "radiosity-solutions"
    folder.mkdir(exist_ok=True)
    return {"TRACER_CACHE_DIR": str(folder)}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """`python -m server` on 127.0.0.1 in a subprocess, with its log in a file. Its `client` sends a
    student's token (`token`) on every request, as api_client's does."""

    def __init__(
        self,
        data_dir: Path,
        workers: int = 1,
        env: dict | None = None,
        port: int | None = None,
        group: bool = False,
        fork: bool = True,
    ):
        self.data_dir, self.workers = Path(data_dir), workers
        self.group = group  # in a process group of its own (its pid is the group's id), as a service manager starts it
        self.fork = fork  # from the zygote (tests/support/zygote.py: the imports done once), else exec'd
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        quiet = {"TRACER_INTERACTIVE_WORKERS": "0", "TRACER_PREVIEWS_AHEAD": "0"}  # as api_client
        quiet |= {"TRACER_ANSWER_AGAIN": "0", "TRACER_LESSONS_AHEAD": "0"}
        quiet |= {"TRACER_MAX_AUTH_FAILURES": "100000"}  # the tests' refused tokens come from one address
        # the mesh reader imported with a first mesh file, not by each of the suite's hundred servers' forkservers
        # (0.6 s of CPU each); tests/server/queue/embedded/test_worker_warm.py tests the preload, on by default
        quiet |= {"TRACER_PRELOAD_MESH_READER": "0"}
        self.env = {**os.environ, **quiet, **(env or {})}
        self.log_path = self.data_dir.parent / f"{self.data_dir.name}-server-{self.port}.log"
        self.proc: subprocess.Popen | zygote.Forked | None = None
        self.token = student_token()
        self.client = httpx.Client(base_url=self.url, timeout=30, headers=bearer(self.token))

    def start(self, workers_ready: bool = True) -> Server:
        """Start it and wait until it answers, and (`workers_ready`) until its workers are ready."""
        self.workers_ready = workers_ready
        self.data_dir.mkdir(parents=True, exist_ok=True)
        self.log = open(self.log_path, "ab")  # noqa: SIM115 (closed in stop)
        cmd = [sys.executable, "-m", "server", "--port", str(self.port), "--data-dir", str(self.data_dir)]
        cmd += ["--workers", str(self.workers)]
        self.proc = zygote.start(cmd, env=self.env, cwd=ROOT, log=self.log, new_session=self.group, fork=self.fork)
        wait_for(self._ready, SERVER_START_TIMEOUT, f"the server to start (log: {self.log_path})", interval=0.2)
        return self

    def _ready(self) -> bool:
        assert self.proc.poll() is None, f"server exited: {self.log_tail()}"
        try:
            health = self.client.get("/api/health").json()
        except httpx.TransportError:
            return False
        if not self.workers_ready:
            return True
        return all(w["ready"] for w in health["workers"]) and len(health["workers"]) == self.workers

    def log_text(self) -> str:
        """The whole log: what a test looks for in it may be anywhere (a slow start's health polls fill it)."""
        return self.log_path.read_text(errors="replace")

    def log_tail(self, chars: int = 5000) -> str:
        """The log's end, for a failure's message."""
        return self.log_text()[-chars:]

    def worker_pids(self) -> list[int]:
        return [w["pid"] for w in self.client.get("/api/health").json()["workers"] if w["alive"]]

    def stop(self, sig: int = signal.SIGTERM) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        if self.proc is not None:
            self.log.close()
        self.proc = None

    def __enter__(self) -> Server:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
        self.client.close()


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie still answers signal 0: look at its state
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"
