"""A worker host of the Redis backend: `python -m server.worker --redis URL [--device cpu] [--threads N]
[--queues interactive batch] [--name NAME] [--no-fork]`, on any machine that has the project installed.

It loads the render kernels once, at start-up, before RQ forks anything; then an RQ worker takes
tries from the queues (server/queue/redis/workers.py) and runs each in a forked work horse, which inherits the
loaded kernels, or in its own process (a CUDA device, `--no-fork`). The try itself is server/queue/redis/horse.py's.

Stopping (SIGTERM or Ctrl-C): the host passes the signal to its work horse (which RQ puts in a process group
of its own, so a signal to the host's group misses it), the try gives its job back at its next check
(within a band of rows), then the host exits; a horse that has not ended `HORSE_STOP_GRACE` seconds later
is killed, and a second signal kills it at once. A horse stopped by a SIGTERM of its own (a service manager
that signals every process of its unit) gives its try back too, and so does a horse whose host is gone (a
SIGKILL to the host's group). None of this waits on Redis, so a host whose Redis has gone away stops too.
"""

from __future__ import annotations

import argparse
import faulthandler
import logging
import os
import signal
import sys
import time
from pathlib import Path

import redis
from pydantic import ValidationError
from rq import Queue
from rq.exceptions import StopRequested

from server.core.credentials import masked
from server.core.settings import explain, load_settings
from server.queue.redis import events as ev
from server.queue.redis.horse import HOST, STOP, connect
from server.queue.redis.horse import run_try as run_try  # RQ jobs queued before the split name it here
from server.queue.redis.workers import DEFAULT_LOST_AFTER, HORSE_STOP_GRACE, HostWorker, InProcessWorker

log = logging.getLogger(__name__)

DEFAULT_CACHE_DIR = Path.home() / ".cache" / "raytrace-edu" / "radiosity"  # without --cache-dir, TRACER_CACHE_DIR
SETTINGS = ("redis_url", "redis_url_file", "render_threads", "cache_dir")  # Settings' fields the command line sets


def _ask_to_stop(signum, frame) -> None:
    """The host's handler of SIGTERM and SIGINT outside RQ's loop (waiting for Redis, starting a worker)."""
    STOP.set()


def _outside_rq() -> None:
    """This host's signal handlers, outside RQ's loop (which has its own: HostWorker.request_stop)."""
    signal.signal(signal.SIGTERM, _ask_to_stop)
    signal.signal(signal.SIGINT, _ask_to_stop)


def main(argv: list[str] | None = None) -> int:
    from tracer.assets import import_mesh_reader
    from tracer.kernels.parallel import default_threads, device_arg, is_cuda
    from tracer.rendering.progressive import load_kernels

    p = argparse.ArgumentParser(
        prog="server.worker",
        description="A worker host: render jobs from the API's Redis queue (python -m server --redis URL).",
    )
    p.add_argument("--settings", help="a settings file of TRACER_*=value lines (default: $TRACER_SETTINGS_FILE)")
    p.add_argument(
        "--redis",
        dest="redis_url",
        metavar="URL",
        help="the Redis the API uses (redis://host:6379/0), or TRACER_REDIS_URL; with a password, rather "
        "--redis-url-file (a command line is shown by ps)",
    )
    p.add_argument(
        "--redis-url-file",
        metavar="PATH",
        help="a file whose first line is the Redis URL, password included (or TRACER_REDIS_URL_FILE)",
    )
    p.add_argument(
        "--device", default="cpu", type=device_arg, help="Warp device to render on: cpu (default), cuda:0, ..."
    )
    p.add_argument(
        "--threads",
        dest="render_threads",
        type=int,
        help="render threads (default TRACER_RENDER_THREADS, else every core; a CUDA device: whole images)",
    )
    p.add_argument(
        "--queues",
        nargs="+",
        default=list(ev.QUEUES),
        choices=ev.QUEUES,
        help="the lanes to take jobs from, in order (default: interactive batch; a host for the page: interactive)",
    )
    p.add_argument("--name", help="this worker's name (default: host.pid)")
    p.add_argument(
        "--cache-dir",
        help="where this host keeps radiosity solutions by their scene's content (default TRACER_CACHE_DIR, else "
        f"{DEFAULT_CACHE_DIR})",
    )
    p.add_argument(
        "--no-fork",
        action="store_true",
        help="run each try in this process, not in a forked work horse (always so on a CUDA device)",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="check the command line and the Redis URL (its file read), say what would start, and exit (0) "
        "without connecting: a unit's ExecStart with --check (deploy/)",
    )
    args = p.parse_args(argv)  # an unknown device: "warp has no device cuda:0 here; available: cpu", exit 2
    given = {k: v for k in SETTINGS if (v := getattr(args, k)) is not None}
    if "redis_url" in given or "redis_url_file" in given:  # the command line's URL, not the environment's other one
        given = {"redis_url": None, "redis_url_file": None, **given}
    try:  # the API's settings (server/core/settings.py): the command line's, the environment's, a settings file's
        settings = load_settings(args.settings, **given)
    except ValidationError as exc:  # each setting by the name it was given (an option, or its TRACER_ variable)
        p.error(explain(exc, {a.dest: a.option_strings[0] for a in p._actions if a.dest in given}))
    except FileNotFoundError as exc:
        p.error(str(exc))
    url = settings.redis_url
    if not url:
        p.error("the Redis URL is missing: give --redis URL or --redis-url-file PATH (or TRACER_REDIS_URL, "
                "TRACER_REDIS_URL_FILE)")  # fmt: skip
    device = args.device
    cuda = is_cuda(device)
    threads = 1 if cuda else settings.render_threads or default_threads()
    cache = str(settings.cache_dir or DEFAULT_CACHE_DIR)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s[%(process)d]: %(message)s")
    if args.check:
        log.info("check: would render on %s (%d thread(s), radiosity cache in %s) from %s, lanes %s", device,
                 threads, cache, masked(url), " ".join(args.queues))  # fmt: skip
        return 0
    faulthandler.register(signal.SIGUSR2, all_threads=True)  # kill -USR2 <pid>: where is it stuck?
    worker_class = InProcessWorker if cuda or args.no_fork else HostWorker  # CUDA must not be forked
    HOST.update(url=url, device=device, threads=threads, cache=cache)
    HOST["name"] = args.name or f"{HOST['host']}.{os.getpid()}"
    HOST["pid"] = os.getpid()  # a try run in another process runs in a forked work horse
    load_kernels(device)  # once: a forked work horse inherits them, an in-process try finds them (and CUDA) warm
    if settings.preload_mesh_reader:
        import_mesh_reader()  # inherited too: a try's first mesh file does not wait for it
    how = "in this process" if worker_class is InProcessWorker else "in forked work horses"
    log.info("worker host %s: kernels ready on %s, %d thread(s), tries %s", HOST["name"], device, HOST["threads"], how)
    pause, worker, stale = 1.0, None, None
    _outside_rq()
    while not STOP():
        try:
            if stale is not None:  # a worker whose connection was lost: its death first, or the next is refused
                stale.register_death()
                stale = None
            r = connect(url)
            lost_after = float(r.hget(ev.CONFIG, "lost_after") or DEFAULT_LOST_AFTER)
            queues = [Queue(name, connection=r) for name in args.queues]
            worker = worker_class(queues, connection=r, name=HOST["name"], lost_after=lost_after)
            stale = worker  # until its loop ends as it should
            try:
                worker.work(logging_level="INFO", with_scheduler=False)
            finally:
                _outside_rq()
            stale = None
            if not STOP() and not worker._stop_requested:  # RQ quits its loop on a lost connection
                stale = worker
                log.warning("worker host %s: lost Redis; retrying in %.0f s", HOST["name"], pause)
                STOP.wait(pause)
                pause = min(10.0, pause * 2)
            else:
                STOP.set()
        except redis.RedisError as exc:
            if not STOP():
                log.warning("worker host %s: Redis unreachable (%s); retrying in %.0f s", HOST["name"], exc, pause)
                STOP.wait(pause)
                pause = min(10.0, pause * 2)
        except (KeyboardInterrupt, SystemExit, StopRequested):  # (RQ's handler, outside its loop's own catch)
            STOP.set()
    if worker is not None and worker.horse_pid:  # RQ's loop ended without its horse (Redis lost mid-try)
        _end_horse(worker.horse_pid)
    log.info("worker host %s: stopped", HOST["name"])
    return 0


def _end_horse(horse: int) -> None:
    """A work horse left running when the host stops: asked to give its try back, killed if it has not
    ended `HORSE_STOP_GRACE` seconds later."""
    try:
        os.kill(horse, signal.SIGTERM)
        deadline = time.monotonic() + HORSE_STOP_GRACE
        while os.waitpid(horse, os.WNOHANG) == (0, 0):
            if time.monotonic() > deadline:
                os.killpg(horse, signal.SIGKILL)
                os.waitpid(horse, 0)
                return
            time.sleep(0.1)
    except (ChildProcessError, ProcessLookupError):
        pass  # already ended (and reaped)


if __name__ == "__main__":
    sys.exit(main())
