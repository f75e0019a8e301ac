"""The worker pool: render processes started by the server, watched by a supervisor thread.

The supervisor wakes when a worker process ends (or every half second) and
- gives the jobs of a dead worker (a crash, a kill, out of memory) back to the queue while they
  have tries left (`job_attempts`, 2 by default: one retry), else fails them with the reason;
- starts a new worker in its slot (after a growing pause if workers keep dying at start-up);
- kills a worker whose job is past its time limit by `HARD_GRACE` seconds, failing the job (the
  worker itself stops a job at its limit within one band of rows; this is for a render stuck in a
  single long launch).
The API never depends on a worker being alive: it only reads and writes the job store.

Stopping: a worker ignores SIGINT and SIGTERM (a terminal's Ctrl-C, `kill -- -PGID` and a service
manager signal the whole process group), so such a signal never ends a worker nor looks like a
crash to restart it after. The server alone stops its workers: as soon as it is asked to stop
(`stopping()`, set by its own signal handler) the supervisor restarts no worker and closes every
worker's line; each gives its job back to the queue at its next look (within a band of rows) and
exits, and `shutdown` kills those that have not within its timeout. A worker still starting (loading its
kernels, not ready) has no job: it is killed at once rather than waited for.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import wait
from multiprocessing.process import BaseProcess

from server.core import children
from server.core.files import is_disk_full
from server.core.settings import Settings
from server.jobs.lifecycle import LANES, Lane
from server.jobs.store import JobStore
from server.queue.embedded.wakeup import ServerEnd
from server.queue.embedded.worker import worker_main

log = logging.getLogger(__name__)

HARD_GRACE = 10.0  # seconds past a job's time limit before its worker is killed


@dataclass
class Slot:
    index: int
    lanes: tuple = LANES  # the lanes its worker takes jobs from (an interactive slot: interactive only)
    process: BaseProcess | None = None
    line: ServerEnd | None = None  # wake it, hear it is ready, close to stop it (server/queue/embedded/wakeup.py)
    started: float = 0.0
    restarts: int = 0
    failures_in_a_row: int = 0  # deaths soon after start, for the restart pause
    not_before: float = 0.0  # no restart before this time


class WorkerPool:
    def __init__(self, settings: Settings, store: JobStore, stopping: Callable[[], bool] = lambda: False):
        self.settings, self.store = settings, store
        self.stopping = stopping  # the server has been asked to stop (a signal): no more workers, no more jobs
        self.ctx = children.context(
            settings.preload_mesh_reader
        )  # forked from the server's forkserver (server/core/children.py)
        general = [Slot(i) for i in range(settings.workers)]
        extra = [Slot(settings.workers + i, (Lane.interactive,)) for i in range(settings.interactive_workers)]
        self.slots = general + extra if general else []  # no workers at all: no interactive one either
        self._lock = threading.Lock()
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None

    # -- life ---------------------------------------------------------------------------------

    def start(self, kernels: threading.Event | None = None) -> None:
        """Start the workers, or (`kernels`) have the supervisor start them once it is set."""
        if kernels is None:
            for slot in self.slots:
                self._spawn(slot)
        self._thread = threading.Thread(target=self._supervise, args=(kernels,), name="worker-supervisor", daemon=True)
        self._thread.start()

    def shutdown(self, timeout: float = 10.0) -> None:
        """Ask the workers to give their jobs back and exit; kill those that do not in `timeout` s."""
        with self._lock:  # after this, the supervisor starts no worker (it spawns holding the lock)
            self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        starting = [s for s in self.slots if s.process is not None and s.line is not None and not s.line.is_ready()]
        self._stop_workers()
        for slot in starting:  # still loading its kernels (seconds on a loaded machine): it has no job to give back
            process = slot.process
            assert process is not None and process.pid is not None  # (picked above: started)
            process.kill()
            process.join(timeout=5)
            job_id = self.store.running_on(process.pid)  # one claimed in the moment since it was asked
            if job_id is not None:
                self.store.requeue(job_id, process.pid)
        deadline = time.monotonic() + timeout
        for slot in self.slots:
            p = slot.process
            if p is None:
                continue
            p.join(timeout=max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                log.warning("worker %d did not stop in time; killing it", p.pid)
                p.kill()
                p.join(timeout=5)
            self._handle_death(slot, p)
            slot.process = None

    def _stop_workers(self) -> None:
        """Close every worker's line: each reads end-of-file, gives its job back and exits."""
        for slot in self.slots:
            if slot.line is not None:
                slot.line.close()

    def _spawn(self, slot: Slot) -> None:
        if slot.line is not None:
            slot.line.close()
        ours, theirs = self.ctx.Pipe()  # a socket pair: no semaphore to leak (server/queue/embedded/wakeup.py)
        plain = self.settings.model_dump(mode="json", exclude={"instructor_token"})  # a worker needs no secret
        p = self.ctx.Process(
            target=worker_main,
            args=(plain, theirs, [str(x) for x in slot.lanes]),
            name=f"render-worker-{slot.index}",
            daemon=True,
        )
        try:
            p.start()
        finally:
            theirs.close()  # the worker has its own copy; ours would hide its end-of-file
        slot.process, slot.line, slot.started = p, ServerEnd(ours), time.monotonic()
        log.info("started render worker %d (pid %d)", slot.index, p.pid)

    def notify(self) -> None:
        """A job was queued: wake the idle workers now rather than at their next look at the queue."""
        for slot in self.slots:  # no pool lock: the supervisor calls this while holding it
            line = slot.line
            if line is not None:
                line.wake()

    # -- supervision --------------------------------------------------------------------------

    def _supervise(self, kernels: threading.Event | None = None) -> None:
        if kernels is not None:
            while not kernels.wait(0.5):  # the server loads the kernels into Warp's cache: the workers then read it
                if self._closing.is_set() or self.stopping():
                    return
            with self._lock:
                if self._closing.is_set() or self.stopping():
                    return
                for slot in self.slots:
                    self._spawn(slot)
        told = False  # the workers were told to stop (the server is stopping)
        while not self._closing.is_set():
            sentinels = [s.process.sentinel for s in self.slots if s.process is not None and s.process.is_alive()]
            if sentinels:
                wait(sentinels, timeout=0.5)
            else:
                self._closing.wait(0.5)
            if self._closing.is_set():
                return
            if self.stopping() and not told:  # stop taking jobs now, before the server waits for its connections
                log.info("stopping: the render workers give their jobs back to the queue")
                with self._lock:
                    self._stop_workers()
                told = True
            try:
                self._check()
            except Exception as exc:  # the supervisor must outlive any surprise (a locked database, ...)
                if is_disk_full(exc):  # it tries again at its next round
                    log.warning("worker supervisor: the disk is full (%s)", exc)
                else:
                    log.exception("worker supervisor")

    def _check(self) -> None:
        now = time.monotonic()
        with self._lock:
            ending = self._closing.is_set() or self.stopping()  # never a new worker while the server stops
            for slot in self.slots:
                p = slot.process
                if p is not None and not p.is_alive():
                    self._handle_death(slot, p)
                    quick = now - slot.started < 10
                    slot.failures_in_a_row = slot.failures_in_a_row + 1 if quick else 0
                    slot.not_before = now + (min(30.0, 2.0 ** (slot.failures_in_a_row - 1)) if quick else 0.0)
                    slot.process = None
                if slot.process is None and now >= slot.not_before and not ending:
                    slot.restarts += 1
                    self._spawn(slot)
        self._kill_overdue()

    def _handle_death(self, slot: Slot, p) -> None:
        code = p.exitcode
        if code is not None and code < 0:
            try:
                how = f"killed by signal {signal.Signals(-code).name}"
            except ValueError:
                how = f"killed by signal {-code}"
        else:
            how = f"exited with status {code}"
        for job_id, status in self.store.worker_died(p.pid, self.settings.job_attempts, f"render worker {how}"):
            log.warning("worker %d %s while rendering job %s: job %s", p.pid, how, job_id, status)
            self.notify()
        if not self._closing.is_set() and not self.stopping():
            log.warning("render worker %d (pid %d) %s", slot.index, p.pid, how)

    def _kill_overdue(self) -> None:
        ours = {s.process.pid: s.process for s in self.slots if s.process is not None and s.process.pid is not None}
        for job in self.store.overdue(HARD_GRACE):
            p = ours.get(job["worker"])
            limit = job["max_seconds"]
            error = f"stopped: over the time limit of {limit:g} s per job (TRACER_MAX_JOB_SECONDS); worker killed"
            if self.store.fail(job["id"], job["worker"], error) and p is not None and p.is_alive():
                log.warning("job %s over its time limit: killing worker %d", job["id"], job["worker"])
                os.kill(job["worker"], signal.SIGKILL)  # = p.pid (ours is by pid)

    # -- information --------------------------------------------------------------------------

    def info(self) -> list[dict]:
        out = []
        for slot in self.slots:
            p = slot.process
            alive = p is not None and p.is_alive()
            out.append(
                {
                    "slot": slot.index,
                    "pid": p.pid if p is not None else None,
                    "alive": alive,
                    "ready": bool(alive and slot.line is not None and slot.line.is_ready()),
                    "restarts": slot.restarts,
                    "job": self.store.running_on(p.pid) if alive and p is not None and p.pid is not None else None,
                    "lanes": [str(x) for x in slot.lanes],
                }
            )
        return out
