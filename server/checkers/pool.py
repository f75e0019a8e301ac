"""Scene checks off the API's event loop: validating a scene (POST /api/validate, and the scene of POST
/api/jobs and POST /api/raytree) and a pixel's samples (POST /api/samples) run in a small pool of
processes, never in the API process.

Validating a scene of 25 000 spheres takes a fifth of a second of Python; four of them in the API's
threads held its interpreter lock long enough to slow every other request (GET /api/jobs/{id} took
0.7 s). Here each check is a task for one of `validate_processes` processes (forked from the server's
forkserver, server/core/children.py; plain data in: the request's body as bytes, the limits; plain data out:
errors, warnings, what the route needs of the scene). The route waits for the answer without holding the event loop, and
- a check that uses more than `max_validate_seconds` of CPU has its process killed (and a new one
  started): the scene is refused as too costly to check;
- a client that goes away while its scene is checked has the process doing it killed and replaced,
  so no CPU goes on burning for an answer nobody reads;
- past `max_validate_waiting` requests waiting for a free process, or `max_validate_waiting_bytes` of their
  bodies held while they wait, a request is answered 429 (a class of 300 submitting in the same second waits
  here with a few megabytes of scenes: both are sized so that it is never refused, docs/service.md "Sizing");
- requests wait in two lines, each first come first served: a small body's (under 64 KB, a student's
  scene) is served before a large one's, so that a class's small submissions pass a crowd of large
  validations (one of which takes a checker a fifth of a second) rather than waiting behind all of them.

The processes are niced like the render workers (the API answers first), watch their server (and exit
when it is gone), and load what they need once at start-up.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import math
import os
import threading
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from enum import StrEnum
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess

import anyio

from server.checkers.tasks import checker_main, loaded
from server.core import children
from server.core.errors import ClientGone, Invalid, TooMany, Unavailable
from server.core.settings import THREAD_FROM, Settings
from tracer.scene import ASSET_DIR

log = logging.getLogger(__name__)

CLIENT_CHECK = 0.05  # seconds between two looks at whether the client is still there, while its scene is checked
WAIT_CHECK = 0.5  # seconds between a waiting request's looks at whether its client is still there
START_TIMEOUT = 120.0  # seconds a new process may take to load what it needs
Gone = Callable[[], Awaitable[bool]]  # has the client gone away? (the route's request.is_disconnected)


class _Clock:
    """Seconds a task has taken: the CPU time its process has used since (from /proc, so a check slowed down
    by a busy machine is not taken for a costly one), or the time since, where /proc cannot say."""

    def __init__(self, pid: int):
        self.pid, self.wall = pid, time.monotonic()
        self.cpu = self._cpu()

    def _cpu(self) -> float | None:
        try:
            with open(f"/proc/{self.pid}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime
        except (OSError, IndexError, ValueError):
            return None

    def __call__(self) -> float:
        now = self._cpu() if self.cpu is not None else None
        if now is not None and self.cpu is not None:
            return now - self.cpu
        return time.monotonic() - self.wall


class CheckerState(StrEnum):
    """A checking process's state (GET /api/health's checkers' `state`)."""

    starting = "starting"  # loading (its process starts, or starts again after a death or a stopped task)
    idle = "idle"  # waits for a task
    busy = "busy"  # runs one


@dataclass
class _Checker:
    index: int
    process: BaseProcess | None = None
    conn: Connection | None = None  # the server's end of the process's line
    state: CheckerState = CheckerState.starting
    task: str | None = None  # what it does while busy: read, validate, summary, samples
    restarts: int = 0


class CheckPool:
    """`settings.validate_processes` checking processes, started with the app; `run` hands one a task."""

    def __init__(self, settings: Settings):
        self.settings = settings
        self.ctx = children.context(
            settings.preload_mesh_reader
        )  # forked from the server's forkserver (server/core/children.py)
        self.checkers = [_Checker(i) for i in range(settings.validate_processes)]
        self._waiters: collections.deque = collections.deque()  # (loop, event) of the requests waiting, oldest first
        self._small: collections.deque = collections.deque()  # the same of small bodies' requests, served first
        self._lock = threading.Lock()
        self._closed = False
        self._waiting_bytes = 0  # the bodies of the requests waiting in both lines

    # -- life

    def start(self) -> None:
        for checker in self.checkers:
            self._restart(checker)

    def _restart(self, checker: _Checker, old=None) -> None:
        """Start the checker's process again, in a thread: the old one (if any) is killed and reaped first."""
        checker.state = CheckerState.starting
        threading.Thread(target=self._start, args=(checker, old), name=f"checker-{checker.index}", daemon=True).start()

    def _start(self, checker: _Checker, old) -> None:
        if old is not None:
            process, conn = old
            process.kill()
            process.join(timeout=10)
            conn.close()
        ours, theirs = self.ctx.Pipe()
        process = self.ctx.Process(target=checker_main, args=(theirs, self.settings.worker_nice, os.getpid(),
                                   self.settings.preload_mesh_reader),
                                   daemon=True, name=f"scene-checker-{checker.index}")  # fmt: skip
        with self._lock:
            if self._closed:
                return
            process.start()
        theirs.close()
        try:
            ready = ours.poll(START_TIMEOUT) and ours.recv() == "ready"
        except (EOFError, OSError):
            ready = False
        with self._lock:
            if self._closed:  # the server stopped meanwhile: this one reads end-of-file and exits
                ours.close()
                process.join(timeout=5)
                return
            if not ready:
                log.error("scene checker %d did not start; starting it again", checker.index)
                checker.restarts += 1
                self._restart(checker, (process, ours))
                return
            checker.process, checker.conn, checker.state = process, ours, CheckerState.idle
            self._wake()

    def _head(self):
        """The waiting request a free checker goes to: the oldest small one, else the oldest (None: nobody)."""
        line = self._small or self._waiters
        return line[0] if line else None

    def _wake(self) -> None:
        """Tell the first waiting request (`_head`) that a checker is free (under the lock; from any thread); it
        stays first in line until it has taken one."""
        head = self._head()
        if head is not None:
            loop, event = head
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:  # its event loop is closed: it is gone
                (self._small if self._small and self._small[0] is head else self._waiters).popleft()
                self._wake()

    def shutdown(self) -> None:
        with self._lock:
            self._closed = True
        for checker in self.checkers:
            if checker.conn is not None:
                checker.conn.close()  # the process reads end-of-file: it exits
        for checker in self.checkers:
            if checker.process is not None:
                if (
                    checker.state == CheckerState.starting
                ):  # still loading (seconds on a loaded machine): nothing of it to keep
                    checker.process.kill()
                checker.process.join(timeout=5)
                if checker.process.is_alive():
                    checker.process.kill()
                    checker.process.join(timeout=5)

    def info(self) -> list[dict]:
        """Each checking process: pid, state (starting, idle, busy), task (while busy), restarts."""
        return [
            {"pid": c.process.pid if c.process is not None and c.state != CheckerState.starting else None,
             "state": c.state, "task": c.task, "restarts": c.restarts}
            for c in self.checkers
        ]  # fmt: skip

    # -- a task

    async def _take(self, gone: Gone, size: int = 0) -> _Checker:
        """An idle checker, marked busy; waits for one without polling, first come first served in its line
        (a body of `size` bytes under THREAD_FROM is small: served first): a request takes a free checker only
        when nobody waits before it (429 past max_validate_waiting waiting in both lines, or past
        max_validate_waiting_bytes of their bodies)."""
        small = size < THREAD_FROM
        waiter, line = None, self._small if small else self._waiters
        try:
            while True:
                with self._lock:
                    free = next((c for c in self.checkers if c.state == CheckerState.idle), None)
                    head = self._head()
                    first = head is waiter if head is not None else waiter is None
                    if small and waiter is None and not self._small:
                        first = True  # no small one waits: the large ones' line is behind this one
                    if free is not None and first:
                        free.state = CheckerState.busy
                        if waiter is not None:
                            line.remove(waiter)
                            self._waiting_bytes -= size
                            waiter = None
                        if any(c.state == CheckerState.idle for c in self.checkers):
                            self._wake()  # another one is free: the next in line takes it
                        return free
                    if waiter is None:
                        full = len(self._waiters) + len(self._small) >= self.settings.max_validate_waiting
                        heavy = self._waiting_bytes + size > self.settings.max_validate_waiting_bytes
                        if full or heavy:
                            setting = "TRACER_MAX_VALIDATE_WAITING" + ("" if full else "_BYTES")
                            raise TooMany(
                                f"too many scenes are being checked; try again later ({setting})", retry_after=2
                            )
                        waiter = (asyncio.get_running_loop(), asyncio.Event())
                        line.append(waiter)
                        self._waiting_bytes += size
                        if free is not None:
                            self._wake()  # it goes before those woken for the free checker: it takes it
                    waiter[1].clear()
                with anyio.move_on_after(WAIT_CHECK):
                    await waiter[1].wait()
                if await gone():
                    raise ClientGone("the client went away")
        finally:
            if waiter is not None:  # gone while waiting (the client left, or a 429 of someone's): out of the line
                with self._lock:
                    head = self._head() is waiter
                    line.remove(waiter)
                    self._waiting_bytes -= size
                    if head and any(c.state == CheckerState.idle for c in self.checkers):
                        self._wake()  # it was woken for a free checker: the next in line takes it

    async def run(self, gone: Gone, task: str, *args, timed: bool = True):
        """The answer of `task` (a name of TASKS) run with `args` in a checking process. A task past the time
        limit (when `timed`) is stopped (422: the scene costs too much to check); one whose client went away
        is stopped too."""
        size = len(args[0]) if args and isinstance(args[0], bytes) else 0
        checker = await self._take(gone, size)
        checker.task = task
        conn, process, answered = checker.conn, checker.process, False
        # a checker is taken once started (idle)
        assert conn is not None and process is not None and process.pid is not None
        limit = self.settings.max_validate_seconds if timed else math.inf
        try:
            await anyio.to_thread.run_sync(conn.send, (task, args))
            spent = _Clock(process.pid)
            while True:
                with anyio.move_on_after(CLIENT_CHECK):
                    await anyio.wait_readable(conn.fileno())  # the answer (or the process's end) is there
                    break
                if await gone():
                    log.info("scene check stopped: the client went away")
                    raise ClientGone("the client went away")
                if spent() >= limit:
                    log.warning("scene check stopped after %g s (TRACER_MAX_VALIDATE_SECONDS)", limit)
                    message = (
                        f"checking the scene took longer than the limit of {limit:g} s (TRACER_MAX_VALIDATE_SECONDS): "
                        "it is too large to check; make it smaller"
                    )
                    raise Invalid([{"path": "", "message": message}])
            kind, value = await anyio.to_thread.run_sync(conn.recv)
            answered = True
        except (EOFError, OSError):
            raise Unavailable("the scene's checking process died; try again") from None
        finally:
            with self._lock:
                checker.task = None
                if answered:
                    checker.state = CheckerState.idle
                    self._wake()
                elif not self._closed:  # stopped mid-task (or dead): a new process takes its place
                    checker.restarts += 1
                    self._restart(checker, (process, conn))
        if kind != "ok":
            raise RuntimeError(f"scene check {task} failed in its process: {value}")
        return value

    async def read(self, gone: Gone, body: bytes):
        """The request's JSON as the route's model reads it, its scene's content left out (`read`); raises
        what json.loads would have raised here, so the answer to a body that is not JSON is the same."""
        return loaded(await self.run(gone, "read", body, timed=False), body)  # bounded by the body's size

    async def validate(self, gone: Gone, body: bytes) -> dict:
        return await self.run(gone, "validate", body, self.settings.limits, ASSET_DIR)

    async def summary(self, gone: Gone, body: bytes) -> dict:
        """The scene's summary (`summary`); 422 with its errors when it is not valid."""
        found = await self.run(gone, "summary", body, self.settings.limits, ASSET_DIR,
                               self.settings.threads_per_worker())  # fmt: skip
        if "errors" in found:
            raise Invalid(found["errors"])
        return found

    async def samples(self, gone: Gone, body: bytes, x: int, y: int) -> dict:
        found = await self.run(gone, "samples", body, self.settings.limits, ASSET_DIR, x, y)
        if "errors" in found:
            raise Invalid(found["errors"])
        return found["samples"]
