"""Helpers of the Redis backend's tests: a real redis-server, the API with `--redis`, worker hosts
(`python -m server.worker`), on loopback or inside the network namespaces of tests/hosts.py.

Every process is started by the test and stopped by PID (a whole process group for a worker host,
whose work horses run in groups of their own: `hosts.Cluster.kill_host` kills a namespace whole)."""

from __future__ import annotations

import atexit
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

from tests.support import zygote
from tests.support.api import free_port, wait_for
from tests.support.scene import ROOT

REDIS = shutil.which("redis-server") or "/usr/bin/redis-server"
LOST_AFTER = 3.0  # seconds: a lost worker host's try runs again this soon in the tests


def redis_argv(port: int, bind: str = "127.0.0.1") -> list[str]:
    """A throwaway redis-server: no persistence, no protected mode (it listens on a test address only)."""
    if not Path(REDIS).exists():
        raise AssertionError("redis-server is missing: ./dev test installs Debian's redis-server")
    return [REDIS, "--port", str(port), "--bind", bind, "--save", "", "--appendonly", "no", "--protected-mode", "no"]


class RedisServer:
    """redis-server on a free loopback port."""

    def __init__(self, log: Path):
        self.port = free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self.log = log
        self.proc: subprocess.Popen | None = None

    def __enter__(self) -> RedisServer:
        self.out = open(self.log, "ab")  # noqa: SIM115 (closed in __exit__)
        self.proc = subprocess.Popen(redis_argv(self.port), stdout=self.out, stderr=subprocess.STDOUT)
        wait_for(self.ping, 20, "redis-server to answer")
        return self

    def client(self, db: int = 0):
        import redis

        return redis.Redis.from_url(self.url.replace("/0", f"/{db}"), socket_timeout=5)

    def ping(self) -> bool:
        import redis

        assert self.proc.poll() is None, f"redis-server exited: {self.log.read_text()[-2000:]}"
        try:
            return self.client().ping()
        except redis.RedisError:
            return False

    def __exit__(self, *exc) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        self.out.close()


def api_argv(data_dir: Path, port: int, redis_url: str, host: str = "127.0.0.1", workers: int = 0) -> list[str]:
    return [
        sys.executable, "-m", "server", "--host", host, "--port", str(port), "--data-dir", str(data_dir),
        "--workers", str(workers), "--redis", redis_url,
    ]  # fmt: skip


def worker_argv(redis_url: str, name: str, threads: int = 1, cache_dir: str | None = None) -> list[str]:
    """A worker host's command line; its radiosity cache in a fresh folder unless given (the tests must not
    find solutions of an earlier run)."""
    cache = cache_dir
    if cache is None:  # removed when the test session ends (these folders used to stay in /tmp, 80 a run)
        cache = tempfile.mkdtemp(prefix="radiosity-cache-")
        atexit.register(shutil.rmtree, cache, True)
    argv = [sys.executable, "-m", "server.worker", "--redis", redis_url, "--threads", str(threads), "--name", name]
    return [*argv, "--cache-dir", cache]


def proc_env(**extra) -> dict:
    """The environment of the test's processes: quick loss detection, frequent previews and snapshots."""
    env = {**os.environ, "TRACER_LOST_AFTER": str(LOST_AFTER), "TRACER_PREVIEW_INTERVAL": "0.2"}
    env["TRACER_SNAPSHOT_INTERVAL"] = "0"  # a snapshot of the film after every pass: a retry continues from it
    env["TRACER_PREVIEWS_AHEAD"] = "0"  # no example previews queued behind the test's own jobs
    env["TRACER_ANSWER_AGAIN"] = env["TRACER_LESSONS_AHEAD"] = "0"  # each job rendered, none of the lessons' ahead
    env["TRACER_MAX_AUTH_FAILURES"] = "100000"  # the tests' refused tokens all come from loopback
    env["TRACER_PRELOAD_MESH_READER"] = "0"  # imported with a first mesh file (as Server's: tests/support/api.py)
    env.update({k: str(v) for k, v in extra.items()})
    return env


class Process:
    """A program started here (loopback tests), in a process group of its own, its output in a log."""

    def __init__(self, argv: list[str], log: Path, env: dict | None = None, fork: bool = True):
        self.argv, self.log_path, self.env = argv, log, env or proc_env()
        self.fork = fork  # `python -m server` and `-m server.worker` from their zygote (tests/support/zygote.py)
        self.proc: subprocess.Popen | zygote.Forked | None = None

    def start(self) -> Process:
        self.out = open(self.log_path, "ab")  # noqa: SIM115 (closed in stop)
        self.proc = zygote.start(self.argv, env=self.env, cwd=ROOT, log=self.out, new_session=True, fork=self.fork)
        return self

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")[-6000:]

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 30) -> None:
        if self.alive():
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        if self.proc is not None:
            self.out.close()
            self.proc = None


class Api(Process):
    """The API with the Redis backend on a loopback port, and an HTTP client to it."""

    def __init__(self, data_dir: Path, redis_url: str, port: int | None = None, env: dict | None = None):
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        data_dir.mkdir(parents=True, exist_ok=True)
        super().__init__(api_argv(data_dir, self.port, redis_url), data_dir.parent / f"api-{self.port}.log", env)
        self.client = httpx.Client(base_url=self.url, timeout=30)

    def start(self) -> Api:
        super().start()
        wait_for(self._up, 120, f"the API to start (log: {self.log_path})", interval=0.2)
        return self

    def _up(self) -> bool:
        assert self.alive(), f"the API exited: {self.log()}"
        try:
            return self.client.get("/api/health").status_code == 200
        except httpx.TransportError:
            return False

    def health(self) -> dict:
        return self.client.get("/api/health").json()

    def wait_hosts(self, n: int, timeout: float = 120) -> list[dict]:
        return wait_for(lambda: len(w := self.health()["workers"]) >= n and w, timeout, f"{n} worker host(s)")

    def submit(self, scene: dict) -> dict:
        r = self.client.post("/api/jobs", json={"scene": scene})
        assert r.status_code == 202, r.text
        return r.json()

    def job(self, job_id: str) -> dict:
        r = self.client.get(f"/api/jobs/{job_id}")
        assert r.status_code == 200, r.text
        return r.json()

    def wait(self, job_id: str, condition, what: str, timeout: float = 120) -> dict:
        return wait_for(lambda: condition(j := self.job(job_id)) and j, timeout, what, interval=0.1)


def host_log_text(path: Path) -> str:
    return path.read_text(errors="replace")[-4000:] if path.exists() else ""


def dumps(obj) -> str:
    return json.dumps(obj, separators=(",", ":"))


def settle(seconds: float) -> None:
    """Give the processes a moment (bounded; used only where nothing can be polled)."""
    time.sleep(seconds)
