"""The pools' processes start from the server's forkserver (server/core/children.py): the heavy imports made there
once, not in each child; the forkserver deaf to the process group's SIGTERM, so that the children it started are
still seen alive (their exit codes come through it)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from server.core import children
from server.core.settings import Settings

PRELOADED = ("numpy", "warp", "trimesh", "tracer.rendering.progressive", "server.queue.embedded.worker")


def _report(conn) -> None:
    """A child's answer: which of PRELOADED it found imported as it started, and its parent."""
    import warp as wp

    cuda = (os.environ.get("CUDA_VISIBLE_DEVICES"), wp.is_cuda_available())
    conn.send(([m for m in PRELOADED if m in sys.modules], os.getppid(), cuda))
    conn.close()


def _grading_process_answer() -> tuple[int, tuple[str | None, bool]]:
    """A grading process's parent, its OMP_NUM_THREADS, and whether an OpenMP runtime is loaded yet (FLIP's comes
    at its first image test: after the setting, so it honours it)."""
    with open("/proc/self/maps") as maps:
        gomp = "libgomp" in maps.read()
    return os.getppid(), (os.environ.get("OMP_NUM_THREADS"), gomp)


def _child_answer(ctx) -> tuple[list[str], int, int]:
    ours, theirs = ctx.Pipe()
    p = ctx.Process(target=_report, args=(theirs,), daemon=True)
    p.start()
    theirs.close()
    try:
        assert ours.poll(120), "the child did not answer"
        found, parent, cuda = ours.recv()
    finally:
        ours.close()
    p.join(timeout=30)
    assert p.exitcode == 0
    # CUDA hidden from the whole tree (server/core/forkserver.py): initialised before a fork, it would be broken
    assert cuda == ("", False)
    return found, parent, p.pid


def test_children_start_from_a_forkserver_with_the_imports_made():
    ctx = children.context()
    assert ctx.get_start_method() == "forkserver"
    found, parent, pid = _child_answer(ctx)
    assert found == list(PRELOADED)  # a spawned child imports them itself, after starting
    assert parent != os.getpid()  # the forkserver's child, not ours
    again = _child_answer(ctx)
    assert again[1] == parent  # one forkserver for all


def test_children_the_forkserver_outlives_a_sigterm_of_the_group():
    ctx = children.context()
    _, forkserver, _ = _child_answer(ctx)
    os.kill(forkserver, signal.SIGTERM)  # what `kill -- -PGID` sends it
    found, parent, _ = _child_answer(ctx)  # answered and reaped through the same forkserver
    assert parent == forkserver
    assert found == list(PRELOADED)


def test_children_the_pools_use_the_forkserver(tmp_path):
    from server.checkers.pool import CheckPool
    from server.grading.pool import GradingPool
    from server.jobs.store import JobStore
    from server.queue.embedded.pool import WorkerPool

    settings = Settings(data_dir=tmp_path, workers=1, validate_processes=1)
    assert WorkerPool(settings, JobStore(tmp_path)).ctx.get_start_method() == "forkserver"
    assert CheckPool(settings).ctx.get_start_method() == "forkserver"
    grading = GradingPool(1)
    try:  # a grading process: the forkserver's child, FLIP's OpenMP told one thread before it loads
        parent, omp = grading.submit(_grading_process_answer).result(timeout=120)
        assert parent == _child_answer(children.context())[1]
        assert omp == ("1", False)
    finally:
        grading.shutdown()


def _busy_until_its_server_ends(server: int) -> None:
    children.watch_server(server)
    time.sleep(120)  # a long task: only the watch ends it


def test_children_a_busy_child_ends_with_its_server_not_its_parent():
    """A child in the middle of a task ends when its server is killed, though its parent, the forkserver, lives on
    (it waits for every child it forked: watching the parent, the two would wait for each other)."""
    server = subprocess.Popen(["sleep", "300"])  # stands in for the server: a process that can be SIGKILLed
    try:
        ctx = children.context()
        child = ctx.Process(target=_busy_until_its_server_ends, args=(server.pid,), daemon=True)
        child.start()
        forkserver = _child_answer(ctx)[1]
        assert child.is_alive()
        server.kill()
        server.wait(timeout=30)
        child.join(timeout=30)
        assert child.exitcode == 0, child.exitcode
        os.kill(forkserver, 0)  # the forkserver is still there: the child did not wait for it
    finally:
        server.kill()
