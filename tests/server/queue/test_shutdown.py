"""Stopping `python -m server` the ways it is stopped (issue #15, item 9): SIGTERM to its whole process group
(`kill -- -PGID`, a service manager) and Ctrl-C (SIGINT to the terminal's group), with a long job running,
one queued and an event stream open. The server stops taking jobs, its worker gives its job back, no
worker is started again (its log), and it exits within a bound; started again, the running job is back
in the queue as it was (its try not counted) and the queued one is still there.

A worker ignores the group's signals: the server alone stops it (server/queue/embedded/pool.py), so a signal is never a
crash to restart it after, and its job is given back, not lost."""

from __future__ import annotations

import os
import signal
import subprocess
import threading

import httpx
import pytest

from tests.support.api import Server, job, long_scene, pid_alive, submit, tiny_scene, wait_finished, wait_for

EXIT_BOUND = 60  # seconds: a bound on the exit, not a speed measurement (about one here; generous for a loaded CI)


def follow(url: str, events: list[str]) -> threading.Thread:
    """Read a job's event stream in a thread (an open connection the server must not wait on)."""

    def read() -> None:
        try:
            with httpx.Client(timeout=None) as c, c.stream("GET", url) as r:
                events.extend(r.iter_lines())
        except httpx.HTTPError as e:
            events.append(f"error: {type(e).__name__}")

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_shutdown_a_signal_to_the_group_gives_the_job_back_and_restarts_no_worker(tmp_path, sig):
    data = tmp_path / "data"
    server = Server(data, workers=1, group=True).start()
    try:
        http = server.client
        # below the small one (priority -1, anyone's to ask): started again, its server renders that one first
        running = submit(http, long_scene(spp=4096), priority=-1)
        # taken before the small one is queued: the interactive lane's job would go first (the niced worker may not
        # have claimed the long one yet on a loaded machine)
        wait_for(lambda: job(http, running["id"])["status"] == "running", 120, "the long job to start")
        # in the batch lane: an interactive job waiting over a second would make the long one give way at its next
        # pass (server/jobs/worker_store.py), and its last try would be that, not the shutdown's
        queued = submit(http, tiny_scene(), lane="batch")
        wait_for(lambda: job(http, running["id"])["preview"] >= 1, 120, "the long job to render a pass")
        assert job(http, queued["id"])["status"] == "queued"
        (worker,) = server.worker_pids()
        events: list[str] = []
        reader = follow(f"{server.url}{running['events_url']}", events)
        wait_for(lambda: events, 30, "the event stream to open")
        os.killpg(server.proc.pid, sig)  # the server, its worker and the multiprocessing helpers alike
        try:
            server.proc.wait(timeout=EXIT_BOUND)
        except subprocess.TimeoutExpired:
            os.killpg(server.proc.pid, signal.SIGKILL)
            raise AssertionError(f"still running {EXIT_BOUND} s after {sig.name}: {server.log_tail()}") from None
        reader.join(timeout=10)
        assert not reader.is_alive(), "the event stream stayed open"
        wait_for(lambda: not pid_alive(worker), 10, "the worker to be gone")
    finally:
        server.stop(signal.SIGKILL)
        server.client.close()
    log = server.log_text()
    assert log.count("started render worker") == 1, log[-5000:]  # never one more, during the shutdown or before it
    assert "killed by signal" not in log and "Traceback" not in log, log[-5000:]
    assert "back in the queue (worker stopping)" in log, log[-5000:]

    with Server(data, workers=0) as again:  # started again: nothing lost, nothing counted against the job
        back = job(again.client, running["id"])
        assert back["status"] == "queued" and back["attempts"] == 0 and back["error"] is None, back
        assert back["tries"][-1]["outcome"] == "given back", back["tries"]
        assert job(again.client, queued["id"])["status"] == "queued"
    with Server(data, workers=1) as third:  # and a worker takes them again
        assert wait_finished(third.client, queued["id"], timeout=120)["status"] == "done"
        wait_for(lambda: job(third.client, running["id"])["status"] == "running", 120, "the long job to resume")
        assert third.client.delete(f"/api/jobs/{running['id']}").status_code == 202


def test_shutdown_a_server_stopped_while_its_workers_start_keeps_its_queued_job(tmp_path):
    """SIGTERM the moment the API answers, its worker still loading its kernels: the server exits (a worker
    that is not ready is not waited for) and the job queued before is still queued, its try not counted."""
    data = tmp_path / "data"
    with Server(data, workers=0) as first:
        queued = submit(first.client, long_scene(spp=4096))
    server = Server(data, workers=1).start(workers_ready=False)
    try:
        server.proc.send_signal(signal.SIGTERM)
        assert server.proc.wait(timeout=EXIT_BOUND) in (0, -signal.SIGTERM), server.log_tail()
    finally:
        server.stop(signal.SIGKILL)
        server.client.close()
    log = server.log_text()
    assert "Traceback" not in log and "while rendering job" not in log, log[-5000:]
    with Server(data, workers=0) as again:
        again.client.headers.update(first.client.headers)
        back = job(again.client, queued["id"])
        assert back["status"] == "queued" and back["attempts"] == 0 and back["error"] is None, back
