"""The Redis URL's password (issue #32, item 6) through real processes: a redis-server that requires a password,
the API given the URL in a file (`python -m server --redis-url-file`) with one local worker host, and a job
rendered through them. The password was printed in the start-up log and shown by ps on the API's and its worker
hosts' command lines; now it is in neither the logs nor any of their command lines."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.support.api import free_port, student_token, tiny_scene, wait_for
from tests.support.queue import REDIS, Process, proc_env, redis_argv

PASSWORD = "s3cret-redis-pw-of-the-test"


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid`, and theirs (from /proc)."""
    out, todo = [], [pid]
    while todo:
        parent = todo.pop()
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rpartition(")")[2].split()
            except OSError:
                continue
            if int(fields[1]) == parent:
                out.append(int(stat.parent.name))
                todo.append(int(stat.parent.name))
        if len(out) > 64:  # bounded: the API has a handful
            break
    return out


def cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def test_queue_redis_secret_the_password_is_in_no_log_and_on_no_command_line(tmp_path):
    import httpx
    import redis

    port = free_port()
    url = f"redis://:{PASSWORD}@127.0.0.1:{port}/0"
    with open(tmp_path / "redis.log", "ab") as log:
        server = subprocess.Popen([*redis_argv(port), "--requirepass", PASSWORD], stdout=log, stderr=log)
    assert Path(REDIS).exists()
    api = None
    try:
        wait_for(lambda: _ping(redis, url), 20, "redis-server to answer")
        (tmp_path / "redis-url").write_text(url + "\n")
        api_port = free_port()
        argv = [sys.executable, "-m", "server", "--port", str(api_port), "--data-dir", str(tmp_path / "data")]
        argv += ["--workers", "1", "--redis-url-file", str(tmp_path / "redis-url")]
        api = Process(argv, tmp_path / "api.log", proc_env(), fork=False).start()  # exec'd: ps shows its own argv
        http = httpx.Client(
            base_url=f"http://127.0.0.1:{api_port}", timeout=30, headers={"Authorization": f"Bearer {student_token()}"}
        )

        def hosts_ready() -> bool:
            assert api.alive(), api.log()
            try:
                workers = http.get("/api/health").json()["workers"]
            except httpx.TransportError:
                return False
            return len(workers) == 1 and workers[0]["ready"]

        wait_for(hosts_ready, 120, f"the API and its worker host (log: {api.log_path})", interval=0.2)
        job = http.post("/api/jobs", json={"scene": tiny_scene()}).json()
        done = wait_for(lambda: (j := http.get(f"/api/jobs/{job['id']}").json())["finished"] and j, 120, "the job")
        assert done["status"] == "done", done  # the worker host reached the Redis that needs the password
        health = http.get("/api/health").text
        lines = [cmdline(p) for p in [api.pid, *children(api.pid)]]
        assert any("server.worker" in line for line in lines), lines
        for shown in (api.log(), health, *lines):
            assert PASSWORD not in shown
        assert "Redis at redis://:***@127.0.0.1" in api.log()
        http.close()
    finally:
        if api is not None:
            api.stop()
        server.terminate()
        server.wait(timeout=10)


def _ping(redis, url: str) -> bool:
    try:
        return redis.Redis.from_url(url, socket_timeout=2).ping()
    except redis.RedisError:
        return False
