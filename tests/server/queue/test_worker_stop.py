"""Stopping a worker host (`python -m server.worker`, issue #24 item 8): RQ forks each try into a work horse
in a process group of its own, so a signal to the host's group never reaches it. A real redis-server, the
API with `--redis` and a forking host of one thread on loopback, with a long render in its horse.

- SIGTERM to every process of the host, as a service manager stopping its whole unit sends it (systemd's
  `KillMode=control-group`): the horse gives its try back (outcome "given back", not counted) and the host
  exits 0, the horse gone (twice: a signal of its host's and one of its own, whose handlers must not hang
  on each other);
- SIGKILL to the host's process group (`kill -9 -- -PGID`): the horse, missed by the signal, sees its
  host gone, gives its try back and ends;
- SIGTERM to a host whose Redis has gone away: it exits.

The bounds below are on an end that must come, not speed measurements: each stop takes about a second here."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pytest

from tests.support.api import long_scene, pid_alive, wait_for
from tests.support.queue import Api, Process, RedisServer, worker_argv

STOP_BOUND = 120  # seconds: an end that must come (about a second here; a CI run under two processes once passed 60)


def stopped(host: Process) -> int:
    """The host's exit status once it has ended, within STOP_BOUND; its log in the failure if it does not end."""
    try:
        return host.proc.wait(timeout=STOP_BOUND)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the host did not end within {STOP_BOUND} s of its SIGTERM; its log:\n{host.log()}")


@pytest.fixture(scope="module")
def api(tmp_path_factory):
    root = tmp_path_factory.mktemp("worker-stop")
    with RedisServer(root / "redis.log") as redis_server:
        api = Api(root / "data", redis_server.url).start()
        try:
            yield api, redis_server, root
        finally:
            api.stop()


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(stat[1]) == pid and stat[0] != "Z":
                found.append(int(entry.name))
    return found


def host_rendering(api: Api, redis_url: str, root: Path, name: str) -> tuple[Process, int, dict]:
    """A forking worker host (in a process group of its own, as a service manager starts it) rendering a long
    job in its work horse: (the host, the horse's pid, the job)."""
    host = Process(worker_argv(redis_url, name), root / f"{name}.log").start()
    api.wait_hosts(1)
    job = api.submit(long_scene(spp=4096))
    api.wait(job["id"], lambda j: j["status"] == "running" and j["preview"] >= 1, "the long job to render a pass")
    (horse,) = wait_for(lambda: children(host.pid), 30, "the host's work horse")
    assert os.getpgid(horse) != os.getpgid(host.pid)  # the premise: a signal to the host's group misses it
    return host, horse, job


def given_back(api: Api, job_id: str) -> dict:
    return api.wait(job_id, lambda j: j["status"] == "queued" and j["tries"][-1]["outcome"], "the try's end")


def clean_up(api: Api, host: Process, horse: int, job: dict) -> None:
    host.stop(signal.SIGKILL)
    if pid_alive(horse):
        os.kill(horse, signal.SIGKILL)
    api.client.delete(f"/api/jobs/{job['id']}")


def test_worker_stop_sigterm_to_the_host_and_its_horse_gives_the_try_back(api):
    api, redis_server, root = api
    host, horse, job = host_rendering(api, redis_server.url, root, "host-term")
    try:
        os.killpg(host.pid, signal.SIGTERM)  # systemd, KillMode=control-group: every process of the unit
        os.kill(horse, signal.SIGTERM)
        assert stopped(host) == 0, host.log()
        wait_for(lambda: not pid_alive(horse), STOP_BOUND, "the work horse to end")
        back = given_back(api, job["id"])
        assert [t["outcome"] for t in back["tries"]] == ["given back"], (back["tries"], host.log())
        assert "Traceback" not in host.log(), host.log()
    finally:
        clean_up(api, host, horse, job)


def test_worker_stop_a_killed_host_s_horse_gives_the_try_back_and_ends(api):
    api, redis_server, root = api
    host, horse, job = host_rendering(api, redis_server.url, root, "host-kill")
    try:
        os.killpg(host.pid, signal.SIGKILL)  # kill -9 -- -PGID: the host, not its horse
        host.proc.wait(timeout=10)
        wait_for(lambda: not pid_alive(horse), STOP_BOUND, "the orphaned work horse to end")
        back = given_back(api, job["id"])
        assert [t["outcome"] for t in back["tries"]] == ["given back"], (back["tries"], host.log())
    finally:
        clean_up(api, host, horse, job)


def test_worker_stop_sigterm_to_a_host_whose_redis_is_gone(tmp_path):
    with RedisServer(tmp_path / "redis.log") as redis_server:
        host = Process(worker_argv(redis_server.url, "host-alone"), tmp_path / "host.log").start()
        try:
            wait_for(lambda: redis_server.client().keys("rq:worker:host-alone"), 120, "the host to register")
            redis_server.__exit__()  # Redis goes away
            wait_for(lambda: "Redis" in host.log().split("kernels ready", 1)[-1], 60, "the host to miss Redis")
            os.killpg(host.pid, signal.SIGTERM)
            assert stopped(host) == 0, host.log()
        finally:
            host.stop(signal.SIGKILL)


def test_worker_stop_the_channel_s_thread_is_told_before_unsubscribe_s_reply_comes(api, monkeypatch):
    """RQ's thread that listens on the host's channel reads it in blocks of 60 s, and RQ told it to end only after
    sending UNSUBSCRIBE: where the thread read the reply first (the order a loaded machine gives; forced here),
    it read on, and the host's stop waited out that block (stops of 30 s and more, killed by the tests' bound).
    HostWorker tells it first: the reply ends it, and the stop does not wait."""
    import time

    from redis.client import PubSub
    from rq import Queue

    from server.queue.redis.horse import connect
    from server.queue.redis.workers import HostWorker

    reads, read = [], PubSub.get_message

    def counted(self, *args, **kwargs):  # each read a thread starts, from the listening thread's first
        reads.append(time.monotonic())
        return read(self, *args, **kwargs)

    monkeypatch.setattr(PubSub, "get_message", counted)
    _, redis_server, _ = api
    conn = connect(redis_server.url.replace("/0", "/7"))
    worker = HostWorker([Queue("interactive", connection=conn)], connection=conn, name="stop-probe")
    worker.subscribe()
    thread, pubsub = worker.pubsub_thread, worker.pubsub
    unsubscribe = pubsub.unsubscribe

    def reply_read_first(*args, **kwargs):  # UNSUBSCRIBE sent, then its reply read before anything else runs
        before = len(reads)
        unsubscribe(*args, **kwargs)
        wait_for(lambda: len(reads) > before or not thread.is_alive(), 20, "the thread to read the reply")

    pubsub.unsubscribe = reply_read_first
    # the first read returns SUBSCRIBE's reply; the second waits for the channel's next message
    wait_for(lambda: len(reads) >= 2, 20, "the thread's second read")
    started = time.monotonic()
    worker.unsubscribe()
    took = time.monotonic() - started
    assert not thread.is_alive()
    assert took < 20, f"the stop waited {took:.0f} s for the listening thread's read"  # about 0.01 s here
    conn.close()
