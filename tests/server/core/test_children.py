"""The pools' processes start from the server's forkserver (server/core/children.py): the heavy imports made there
once, not in each child; the forkserver deaf to the process group's SIGTERM, so that the children it started are
still seen alive (their exit codes come through it)."""

from __future__ import annotations

import os
import signal
import sys

from server.core import children
from server.core.settings import Settings

PRELOADED = ("numpy", "warp", "trimesh", "tracer.rendering.progressive", "server.queue.embedded.worker")


def _report(conn) -> None:
    """A child's answer: which of PRELOADED it found imported as it started, and its parent."""
    import warp as wp

    cuda = (os.environ.get("CUDA_VISIBLE_DEVICES"), wp.is_cuda_available())
    conn.send(([m for m in PRELOADED if m in sys.modules], os.getppid(), cuda))
    conn.close()


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
    from server.jobs.store import JobStore
    from server.queue.embedded.pool import WorkerPool

    settings = Settings(data_dir=tmp_path, workers=1, validate_processes=1)
    assert WorkerPool(settings, JobStore(tmp_path)).ctx.get_start_method() == "forkserver"
    assert CheckPool(settings).ctx.get_start_method() == "forkserver"
