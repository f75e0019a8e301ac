"""Scene checks off the API's event loop: validating a scene (POST /api/validate, and the scene of POST
/api/jobs and POST /api/raytree) and a pixel's samples (POST /api/samples) run in a small pool of
processes, never in the API process.

Validating a scene of 25 000 spheres takes a fifth of a second of Python; four of them in the API's
threads held its interpreter lock long enough to slow every other request (GET /api/jobs/{id} took
0.7 s). Here each check is a task for one of `validate_processes` spawned processes (plain data in:
the request's body as bytes, the limits; plain data out: errors, warnings, what the route needs of
the scene). The route waits for the answer without holding the event loop, and
- a check that uses more than `max_validate_seconds` of CPU has its process killed (and a new one
  started): the scene is refused as too costly to check;
- a client that goes away while its scene is checked has the process doing it killed and replaced,
  so no CPU goes on burning for an answer nobody reads;
- past `max_validate_waiting` requests waiting for a free process, a request is answered 429.

The processes are niced like the render workers (the API answers first), watch their server (and exit
when it is gone), and load what they need once at start-up.
"""

from __future__ import annotations

import asyncio
import collections
import json
import logging
import math
import multiprocessing as mp
import os
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import anyio
from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.routing import APIRoute

from server.errors import ApiError
from server.settings import Settings
from tracer.scene import ASSET_DIR, Limits, SceneError, load_scene

log = logging.getLogger("server.checks")

CLIENT_CHECK = 0.05  # seconds between two looks at whether the client is still there, while its scene is checked
WAIT_CHECK = 0.5  # seconds between a waiting request's looks at whether its client is still there
READ_HERE = 65536  # bytes: a request body smaller than this is parsed in the API process (in well under 1 ms)
START_TIMEOUT = 120.0  # seconds a new process may take to load what it needs
PARENT_CHECK = 1.0  # seconds between a checking process's looks at whether the server is still there


# ----------------------------------------------------------------------------- the tasks (in a process)


def _scene_of(body: bytes, limits: Limits, assets: Path) -> tuple:
    """The request body's scene, validated as POST /api/jobs validates it (the format, the limits, the asset
    files): (Scene, warnings), or raises SceneError."""
    data = json.loads(body)["scene"]  # the body was checked by the route's model: an object with a scene
    return (*load_scene(data, limits, assets=assets), data)


def validate(body: bytes, limits: Limits, assets: Path) -> dict:
    """POST /api/validate's answer."""
    try:
        _, warnings, _ = _scene_of(body, limits, assets)
    except SceneError as exc:
        return {"valid": False, "errors": exc.errors, "warnings": []}
    return {"valid": True, "errors": [], "warnings": warnings}


def summary(body: bytes, limits: Limits, assets: Path, threads: int) -> dict:
    """What POST /api/jobs and POST /api/raytree need of a valid scene (the scene's JSON text, its size and
    estimates), or its `errors`."""
    from tracer import estimate

    try:
        scene, warnings, data = _scene_of(body, limits, assets)
    except SceneError as exc:
        return {"errors": exc.errors}
    solve = estimate.solve_seconds(scene, threads, assets)
    return {
        "text": json.dumps(data), "warnings": warnings, "name": scene.name, "width": scene.film.width,
        "height": scene.film.height, "spp": scene.sampler.spp, "integrator": scene.render.integrator,
        "seconds": estimate.seconds(scene, threads, assets, solve), "solve_seconds": solve,
    }  # fmt: skip


def samples(body: bytes, limits: Limits, assets: Path, x: int, y: int) -> dict:
    """POST /api/samples's answer, or its `errors`."""
    from tracer.compile import compile_scene
    from tracer.samples import pixel_samples

    try:
        scene, _, _ = _scene_of(body, limits, assets)
        # as many positions as a scene may have samples (the service's max_spp), the adaptive grid's included
        return {"samples": pixel_samples(compile_scene(scene, assets, limits=limits), x, y, max_samples=limits.max_spp)}
    except SceneError as exc:
        return {"errors": exc.errors}


def read(body: bytes) -> tuple:
    """A request body's JSON for the route's own model (server/models.py): ("ok", the body with its scene's
    content left out), or why it is not JSON as the API would have said it: ("invalid", message, position)
    for a JSON syntax error, ("unreadable", message) for the rest (not UTF-8, an integer too long, nesting
    too deep for the parser)."""
    try:
        data = json.loads(body)
    except json.JSONDecodeError as exc:
        return "invalid", exc.msg, exc.pos
    except (ValueError, RecursionError) as exc:
        return "unreadable", f"{type(exc).__name__}: {exc}"
    if isinstance(data, dict) and isinstance(data.get("scene"), dict):
        data = {**data, "scene": {}}  # a scene is read, from the same bytes, where it is checked
    return "ok", data


TASKS = {"read": read, "validate": validate, "summary": summary, "samples": samples}


def checker_main(conn, nice: int) -> None:
    """A checking process (spawned): below the API in priority, deaf to the terminal's Ctrl-C and to a SIGTERM
    sent to the server's whole process group (the server stops it: closing its line), gone with its server;
    loads the kernels of the samples from Warp's cache, says it is ready, then answers tasks (name, args)
    until its line closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if nice:
        try:
            os.nice(nice)
        except OSError:
            pass
    threading.Thread(target=_watch_parent, args=(os.getppid(),), name="parent-watch", daemon=True).start()
    from tracer.samples import load_kernels

    load_kernels()
    conn.send("ready")
    while True:
        try:
            name, args = conn.recv()
        except (EOFError, OSError):
            return
        try:
            answer = ("ok", TASKS[name](*args))
        except Exception as exc:  # a bug must answer the request (a 500 in the API), not end the process
            log.exception("scene check %s failed", name)
            answer = ("crash", f"{type(exc).__name__}: {exc}")
        conn.send(answer)


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
        return now - self.cpu if now is not None else time.monotonic() - self.wall


def _watch_parent(parent: int) -> None:
    """End this process once its server is gone (killed without a word: SIGKILL, out of memory), even in the
    middle of a task."""
    while True:
        time.sleep(PARENT_CHECK)
        if os.getppid() != parent:
            os._exit(0)


# ----------------------------------------------------------------------------- the routes' requests


class SceneRequest(Request):
    """The request of a route whose body carries a scene: a large body's JSON is parsed in a checking process,
    not on the event loop (1.6 MB of spheres took 30-50 ms to parse here), and the route's model sees the
    body with an empty scene (`read`; a small body is parsed here, the same way). The route sends the
    request's bytes to be checked (`CheckPool.summary`, ...) and never reads `scene` from its model."""

    async def json(self):
        if not hasattr(self, "_json"):
            body = await self.body()
            if len(body) < READ_HERE:
                self._json = _answer(read(body), body)
            else:
                try:
                    self._json = await self.app.state.checks.read(self, body)
                except ApiError as exc:  # FastAPI would answer anything else raised here with a 400
                    raise HTTPException(exc.status, exc.errors[0]["message"], exc.headers) from None
        return self._json


def _answer(answer: tuple, body: bytes):
    """`read`'s answer as json.loads would have given it: the data, or its exception (the same error answer)."""
    if answer[0] == "invalid":
        raise json.JSONDecodeError(answer[1], body.decode(json.detect_encoding(body), "surrogatepass"), answer[2])
    if answer[0] == "unreadable":
        raise ValueError(answer[1])
    return answer[1]


class SceneRoute(APIRoute):
    """A route whose request is a `SceneRequest` (FastAPI's custom route class)."""

    def get_route_handler(self):
        handler = super().get_route_handler()

        async def route(request: Request) -> Response:
            return await handler(SceneRequest(request.scope, request.receive))

        return route


def scene_post(router: APIRouter, path: str, **options):
    """`@router.post(path, **options)` for a route whose body carries a scene: its request is a SceneRequest."""

    def decorator(endpoint):
        router.add_api_route(path, endpoint, methods=["POST"], route_class_override=SceneRoute, **options)
        return endpoint

    return decorator


# ----------------------------------------------------------------------------- the pool (in the API)


@dataclass
class _Checker:
    index: int
    process: mp.process.BaseProcess | None = None
    conn: object = None  # the server's end of the process's line
    state: str = "starting"  # starting, idle, busy
    task: str | None = None  # what it does while busy: read, validate, summary, samples
    restarts: int = 0


class CheckPool:
    """`settings.validate_processes` checking processes, started with the app; `run` hands one a task."""

    def __init__(self, settings: Settings):
        self.settings = settings
        self.ctx = mp.get_context("spawn")
        self.checkers = [_Checker(i) for i in range(settings.validate_processes)]
        self._waiters: collections.deque = collections.deque()  # (loop, event) of the requests waiting, oldest first
        self._lock = threading.Lock()
        self._closed = False

    # -- life

    def start(self) -> None:
        for checker in self.checkers:
            self._restart(checker)

    def _restart(self, checker: _Checker, old=None) -> None:
        """Start the checker's process again, in a thread: the old one (if any) is killed and reaped first."""
        checker.state = "starting"
        threading.Thread(target=self._start, args=(checker, old), name=f"checker-{checker.index}", daemon=True).start()

    def _start(self, checker: _Checker, old) -> None:
        if old is not None:
            process, conn = old
            process.kill()
            process.join(timeout=10)
            conn.close()
        ours, theirs = self.ctx.Pipe()
        process = self.ctx.Process(target=checker_main, args=(theirs, self.settings.worker_nice), daemon=True,
                                   name=f"scene-checker-{checker.index}")  # fmt: skip
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
            checker.process, checker.conn, checker.state = process, ours, "idle"
            self._wake()

    def _wake(self) -> None:
        """Tell the oldest waiting request that a checker is free (under the lock; from any thread); it stays
        first in line until it has taken one."""
        if self._waiters:
            loop, event = self._waiters[0]
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:  # its event loop is closed: it is gone
                self._waiters.popleft()
                self._wake()

    def shutdown(self) -> None:
        with self._lock:
            self._closed = True
        for checker in self.checkers:
            if checker.conn is not None:
                checker.conn.close()  # the process reads end-of-file: it exits
        for checker in self.checkers:
            if checker.process is not None:
                checker.process.join(timeout=5)
                if checker.process.is_alive():
                    checker.process.kill()
                    checker.process.join(timeout=5)

    def info(self) -> list[dict]:
        """Each checking process: pid, state (starting, idle, busy), task (while busy), restarts."""
        return [
            {"pid": c.process.pid if c.process is not None and c.state != "starting" else None, "state": c.state,
             "task": c.task, "restarts": c.restarts}
            for c in self.checkers
        ]  # fmt: skip

    # -- a task

    async def _take(self, request: Request) -> _Checker:
        """An idle checker, marked busy; waits for one without polling, first come first served: a request
        takes a free checker only when nobody waits before it (429 past max_validate_waiting waiting)."""
        waiter = None
        try:
            while True:
                with self._lock:
                    free = next((c for c in self.checkers if c.state == "idle"), None)
                    first = self._waiters[0] is waiter if self._waiters else waiter is None
                    if free is not None and first:
                        free.state = "busy"
                        if waiter is not None:
                            self._waiters.popleft()
                            waiter = None
                        if any(c.state == "idle" for c in self.checkers):
                            self._wake()  # another one is free: the next in line takes it
                        return free
                    if waiter is None:
                        if len(self._waiters) >= self.settings.max_validate_waiting:
                            raise ApiError(
                                429, "too many scenes are being checked; try again later (TRACER_MAX_VALIDATE_WAITING)",
                                headers={"Retry-After": "2"},
                            )  # fmt: skip
                        waiter = (asyncio.get_running_loop(), asyncio.Event())
                        self._waiters.append(waiter)
                    waiter[1].clear()
                with anyio.move_on_after(WAIT_CHECK):
                    await waiter[1].wait()
                if await request.is_disconnected():
                    raise ApiError(499, "the client went away")
        finally:
            if waiter is not None:  # gone while waiting (the client left, or a 429 of someone's): out of the line
                with self._lock:
                    head = bool(self._waiters) and self._waiters[0] is waiter
                    self._waiters.remove(waiter)
                    if head and any(c.state == "idle" for c in self.checkers):
                        self._wake()  # it was woken for a free checker: the next in line takes it

    async def run(self, request: Request, task: str, *args, timed: bool = True):
        """The answer of `task` (a name of TASKS) run with `args` in a checking process. A task past the time
        limit (when `timed`) is stopped (422: the scene costs too much to check); one whose client went away
        is stopped too."""
        checker = await self._take(request)
        checker.task = task
        conn, process, answered = checker.conn, checker.process, False
        limit = self.settings.max_validate_seconds if timed else math.inf
        try:
            await anyio.to_thread.run_sync(conn.send, (task, args))
            spent = _Clock(process.pid)
            while True:
                with anyio.move_on_after(CLIENT_CHECK):
                    await anyio.wait_readable(conn.fileno())  # the answer (or the process's end) is there
                    break
                if await request.is_disconnected():
                    log.info("scene check stopped: the client went away")
                    raise ApiError(499, "the client went away")
                if spent() >= limit:
                    log.warning("scene check stopped after %g s (TRACER_MAX_VALIDATE_SECONDS)", limit)
                    message = (
                        f"checking the scene took longer than the limit of {limit:g} s (TRACER_MAX_VALIDATE_SECONDS): "
                        "it is too large to check; make it smaller"
                    )
                    raise ApiError(422, [{"path": "", "message": message}])
            kind, value = await anyio.to_thread.run_sync(conn.recv)
            answered = True
        except (EOFError, OSError):
            raise ApiError(503, "the scene's checking process died; try again") from None
        finally:
            with self._lock:
                checker.task = None
                if answered:
                    checker.state = "idle"
                    self._wake()
                elif not self._closed:  # stopped mid-task (or dead): a new process takes its place
                    checker.restarts += 1
                    self._restart(checker, (process, conn))
        if kind != "ok":
            raise RuntimeError(f"scene check {task} failed in its process: {value}")
        return value

    async def read(self, request: Request, body: bytes):
        """The request's JSON as the route's model reads it, its scene's content left out (`read`); raises
        what json.loads would have raised here, so the answer to a body that is not JSON is the same."""
        return _answer(await self.run(request, "read", body, timed=False), body)  # bounded by the body's size

    async def validate(self, request: Request, body: bytes) -> dict:
        return await self.run(request, "validate", body, self.settings.limits, ASSET_DIR)

    async def summary(self, request: Request, body: bytes) -> dict:
        """The scene's summary (`summary`); 422 with its errors when it is not valid."""
        found = await self.run(request, "summary", body, self.settings.limits, ASSET_DIR,
                               self.settings.threads_per_worker())  # fmt: skip
        if "errors" in found:
            raise ApiError(422, found["errors"])
        return found

    async def samples(self, request: Request, body: bytes, x: int, y: int) -> dict:
        found = await self.run(request, "samples", body, self.settings.limits, ASSET_DIR, x, y)
        if "errors" in found:
            raise ApiError(422, found["errors"])
        return found["samples"]
