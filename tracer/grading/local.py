"""The grading CLI's renderer: every render in a worker process of its own, N at a time, each stopped at
its time limit.

The grader takes any `renderer`, a callable from a list of RenderJobs to one Rendered each (renders.py):
`InlineRenderer` renders in this process, the service renders through its job queue (server/grading/runs.py),
and `LocalRenderer` is the same isolation without the service: a slow or broken submission fails alone
(its worker is killed at the limit, or dies, and is replaced) while the others go on. Jobs cross the
process boundary as plain data and each worker renders them with `InlineRenderer`, so the images, and
so the reports, are the ones the other two give.

    with LocalRenderer(workers=2, log_path=out / "workers.log", on_progress=show) as renderer:
        reports = Grader(assignment, base, renderer).grade(submissions)
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import time
from collections import deque
from collections.abc import Callable
from multiprocessing.connection import wait
from pathlib import Path

from tracer.grading.renders import InlineRenderer, Rendered, RenderJob, over_time

log = logging.getLogger("tracer.grading.local")

HARD_GRACE = 10.0  # seconds past a job's limit before its worker is killed (a render stops itself at a pass)
MAX_FAILED_STARTS = 3  # workers that die before their first job, before grading gives up
READY = "ready"  # what a worker says once its kernels are loaded (a job's time starts when it is handed over)
LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s[%(process)d]: %(message)s"


def _worker_main(conn, threads: int | None, log_path: str | None) -> None:
    """A worker process: render each job that arrives on `conn` and send back its Rendered; stop at end of file."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group; the parent stops us
    if log_path is not None:  # standard output and error (Warp's, a crash's traceback) to the log too
        fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.close(fd)
    logging.basicConfig(level=logging.INFO, format=LOG_FORMAT)
    from tracer.rendering.progressive import load_kernels

    load_kernels()  # from Warp's cache: the parent compiled them
    renderer = InlineRenderer(threads)
    log.info("render worker %d ready", os.getpid())
    conn.send(READY)
    while True:
        try:
            job: RenderJob = conn.recv()
        except (EOFError, OSError):
            break
        log.info("job %s: rendering", job.name)
        try:
            result = renderer.one(job)
        except Exception as exc:  # a bug or a broken scene fails the job, not the worker
            log.exception("job %s failed", job.name)
            result = Rendered(error=f"render error: {type(exc).__name__}: {exc}")
        log.info("job %s: %s", job.name, result.error or f"done, {result.spp} spp in {result.seconds:.2f} s")
        conn.send(result)
    log.info("render worker %d stopping", os.getpid())


class _Worker:
    """A worker process, the line to it, and the job it is on."""

    def __init__(self, ctx, threads: int | None, log_path: Path | None):
        self.conn, theirs = ctx.Pipe()
        self.process = ctx.Process(
            target=_worker_main, args=(theirs, threads, None if log_path is None else str(log_path)), daemon=True
        )
        self.process.start()
        theirs.close()  # the worker has its own copy; ours would hide its end of file
        self.ready = False  # it has loaded the kernels and waits for a job
        self.job: int | None = None  # index of the job it renders
        self.deadline = 0.0

    def give(self, index: int, job: RenderJob, grace: float) -> None:
        self.job, self.deadline = index, time.monotonic() + job.max_seconds + grace
        self.conn.send(job)

    def stop(self, kill: bool = False) -> None:
        if kill:
            self.process.kill()
        self.conn.close()
        self.process.join(timeout=10)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()


def _death(process) -> str:
    code = process.exitcode
    if code is not None and code < 0:
        try:
            return f"killed by signal {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with status {code}"


class LocalRenderer:
    """Renders a grader's jobs in `workers` processes of its own (higher priority first), each over
    `threads` threads (default: the cores shared out); `on_progress(done, total)` follows the renders;
    the workers log to `log_path` (else to this process's standard error); a worker still on a job
    `grace` seconds past its limit is killed. Use it in a `with` block, which stops the workers at its end."""

    def __init__(
        self,
        workers: int = 2,
        threads: int | None = None,
        log_path: Path | None = None,
        on_progress: Callable[[int, int], None] | None = None,
        grace: float = HARD_GRACE,
    ):
        self.workers = max(1, workers)
        self.threads = threads or max(1, (os.cpu_count() or 1) // self.workers)
        self.log_path, self.on_progress, self.grace = log_path, on_progress, grace
        self.ctx = mp.get_context("spawn")
        self.pool: list[_Worker] = []
        self.failed_starts = 0

    def __enter__(self) -> LocalRenderer:
        from tracer.rendering.progressive import load_kernels

        load_kernels()  # compile once here, so the workers only read Warp's cache
        if self.log_path is not None:
            Path(self.log_path).parent.mkdir(parents=True, exist_ok=True)
        self.pool = [_Worker(self.ctx, self.threads, self.log_path) for _ in range(self.workers)]
        return self

    def __exit__(self, *exc) -> None:
        for w in self.pool:
            w.stop()
        self.pool = []

    def __call__(self, jobs: list[RenderJob]) -> list[Rendered]:
        if not self.pool:
            raise RuntimeError("LocalRenderer renders inside its `with` block")
        out: list[Rendered | None] = [None] * len(jobs)
        pending = deque(sorted(range(len(jobs)), key=lambda i: -jobs[i].priority))
        done = 0
        self._progress(done, len(jobs))
        while done < len(jobs):
            for w in self.pool:
                if w.ready and w.job is None and pending:
                    i = pending.popleft()
                    w.give(i, jobs[i], self.grace)
            busy = [w for w in self.pool if w.job is not None]
            timeout = max(0.0, min(w.deadline for w in busy) - time.monotonic()) if busy else None
            ready = wait([w.conn for w in self.pool] + [w.process.sentinel for w in self.pool], timeout)
            for k, w in enumerate(self.pool):
                message, died = None, False
                if w.conn in ready:
                    try:
                        message = w.conn.recv()
                    except (EOFError, OSError):  # it died (while sending)
                        died = True
                elif w.process.sentinel in ready:
                    died = True
                if isinstance(message, str):  # READY
                    w.ready = True
                    continue
                if w.job is None:
                    if died:  # at start-up (its log says why): try again, a few times
                        self.failed_starts += 1
                        if self.failed_starts > MAX_FAILED_STARTS:
                            raise RuntimeError(f"the render workers could not start (see {self.log_path or 'stderr'})")
                        self.pool[k] = self._replace(w)
                    continue
                i, job = w.job, jobs[w.job]
                if message is not None:
                    out[i] = message
                    w.job = None
                elif died:  # a crash: the report says how, the log has the rest
                    w.process.join()
                    out[i] = Rendered(error=f"the render process {_death(w.process)}")
                    self.pool[k] = self._replace(w)
                elif time.monotonic() >= w.deadline:  # stuck in one long pass: the render cannot stop itself
                    out[i] = Rendered(error=over_time(job.max_seconds, job.limit_source) + "; its worker was killed")
                    self.pool[k] = self._replace(w, kill=True)
                else:
                    continue
                done += 1
                self._progress(done, len(jobs))
        return out  # type: ignore[return-value]

    def _replace(self, w: _Worker, kill: bool = False) -> _Worker:
        w.stop(kill=kill)
        return _Worker(self.ctx, self.threads, self.log_path)

    def _progress(self, done: int, total: int) -> None:
        if self.on_progress:
            self.on_progress(done, total)
