"""The server's line to a render worker (server/queue/embedded/wakeup.py)."""

from __future__ import annotations


def test_channel_wakes_readies_and_stops():
    """The server's line to a worker (a socket pair, no semaphores): wake, ready, and close = stop."""
    import multiprocessing as mp
    import time

    from server.queue.embedded.wakeup import ServerEnd, WorkerEnd

    ours, theirs = mp.get_context("spawn").Pipe()
    server, worker = ServerEnd(ours), WorkerEnd(theirs)
    assert not server.is_ready()
    worker.ready()
    assert server.is_ready() and server.is_ready()  # it stays ready
    for _ in range(100_000):  # a busy worker's wakes pile up: never blocking the API
        server.wake()
    start = time.monotonic()
    worker.wait(5.0)  # pending wakes: returns at once, and drains them
    assert time.monotonic() - start < 1.0 and not worker.stopping()
    start = time.monotonic()
    worker.wait(0.2)  # none pending: the full timeout
    assert time.monotonic() - start >= 0.19
    server.close()
    assert worker.stopping()
    server.wake()  # after close: nothing happens (never a write to a reused descriptor)
    start = time.monotonic()
    worker.wait(5.0)  # a stopping worker does not sleep
    assert time.monotonic() - start < 1.0
    theirs.close()
