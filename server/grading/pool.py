"""The grading processes: where each student's work is done (tracer/grading/tasks.py: reading and checking
a submission, the image tests), never in the API process."""

from __future__ import annotations

import gc
import logging
import os
import signal
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import cast

from server.core import children

log = logging.getLogger(__name__)

STOP_GRACE = 2.0  # seconds a grading process has at shutdown to finish its task before it is killed


def _pool_process(nice: int, server: int) -> None:
    """A grading process starts: below the API (like the render workers), deaf to the terminal's Ctrl-C and
    the group's SIGTERM (the server stops the pool), watching that its server lives, the grading modules loaded
    before the first task."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the group's stop signal too: the server ends the pool
    if nice:
        os.nice(nice)
    # one thread per process, before FLIP loads its OpenMP runtime (here, never in the forkserver: it is not in
    # children.PRELOAD): the pool is the parallelism, and OpenMP's threads spinning on cores the renders use made a
    # 96x72 FLIP take 100 ms instead of 7 (bench/grading.py)
    os.environ["OMP_NUM_THREADS"] = "1"
    children.watch_server(server)  # Python's pool cannot tell: each process holds both ends of the pipe it waits on
    import tracer.grading.tasks  # noqa: F401  (numpy, FLIP, scikit-image: once per process)


class GradingPool:
    """Worker processes for the runs' per-student work (tracer/grading/tasks.py): `processes` of them,
    forked from the server's forkserver (server/core/children.py: nothing of the API's state crosses, tasks are
    plain data; numpy, Warp and the tracer already imported: 0.05 s of CPU to start one against 0.35-0.6 s
    spawned), niced like the render workers,
    started at the first task and kept. A process that dies breaks Python's pool: the next `submit`
    starts a new one, and each run submits again what it had lost (server/grading/run_tasks.py)."""

    def __init__(self, processes: int, nice: int = 0, mesh_reader: bool = True):
        self.processes, self.nice, self.mesh_reader = max(1, processes), nice, mesh_reader
        self._executor: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()
        self.closed = False

    def _new(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            self.processes,
            mp_context=children.context(self.mesh_reader),
            initializer=_pool_process,
            initargs=(self.nice, os.getpid()),
        )

    def submit(self, fn, /, *args, **kwargs) -> Future:
        with self._lock:
            if self.closed:
                raise RuntimeError("the grading pool is shut down")
            if self._executor is None:
                self._executor = self._new()
            try:
                return self._executor.submit(fn, *args, **kwargs)
            except BrokenProcessPool:
                log.warning("a grading process died: starting new ones")
                self._executor.shutdown(wait=False, cancel_futures=True)
                self._executor = self._new()
                return self._executor.submit(fn, *args, **kwargs)

    def pids(self) -> list[int]:
        executor = self._executor
        return sorted((getattr(executor, "_processes", None) or {}).keys()) if executor else []

    def shutdown(self, grace: float = STOP_GRACE) -> None:
        """Stop the processes (a task still running after `grace` seconds is killed: its run is resumed by the
        next server) and release the pool's queues. Python's pool keeps them (five named POSIX semaphores) until
        they are collected; a server that ends by its signal (uvicorn re-raises SIGTERM and SIGINT) runs no
        finalizer after, and multiprocessing's resource tracker warned "5 leaked semaphore objects" at each stop."""
        with self._lock:
            self.closed = True
            executor, self._executor = self._executor, None
        if executor is None:
            return
        # joins the processes, then lets go of the queues (a thread: typeshed types the private attribute wrongly)
        manager = cast(threading.Thread | None, executor._executor_manager_thread)
        processes = list((executor._processes or {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        if manager is not None:
            manager.join(timeout=grace)
        for p in processes:
            if p.is_alive():
                log.warning("grading process %d did not stop in %.0f s; killing it", p.pid, grace)
                p.kill()
        if manager is not None:
            manager.join(timeout=10)
        del executor, manager, processes
        gc.collect()  # the pool's queues are in reference cycles: their semaphores are unlinked as they go
