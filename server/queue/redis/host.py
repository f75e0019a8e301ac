"""A worker host of the Redis backend: `python -m server.worker --redis URL [--device cpu] [--threads N]
[--queues interactive batch] [--name NAME] [--no-fork]`, on any machine that has the project installed.

It loads the render kernels once, at start-up, before RQ forks anything; then an RQ worker takes
tries from the queues and runs each in a forked work horse, which inherits the loaded kernels. The
work horse renders the try (server/queue/render_try.py) and reports through `RedisChannel`: events on the
stream, files as keys (server/queue/redis/events.py). The API applies them to its store.

On a CUDA device (`--device cuda:0`) nothing forks: CUDA does not survive a fork (a child forked
after CUDA was initialised cannot use it), and initialising CUDA afresh in every work horse would cost
more than a GPU render. So a GPU host initialises CUDA and loads the kernels once, in its one process,
and runs each try there (`InProcessWorker`, RQ's SimpleWorker with this host's heartbeats); the CUDA
context stays warm from try to try. `--no-fork` picks that class on the CPU too (the tests use it).

Heartbeats: the RQ worker refreshes its try's entry in RQ's started registry every
`lost_after / 4` seconds with an expiry of `lost_after` (the API's setting, read from Redis), so a
host that dies or is cut off loses its try after `lost_after` seconds: the API finds the expired
entry and queues the job's next try for another host.

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
import socket
import sys
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import cast

import redis
from pydantic import ValidationError
from redis.typing import EncodableT, FieldT
from rq import Queue, Worker, worker_registration
from rq.exceptions import StopRequested
from rq.utils import now
from rq.worker import WorkerStatus

from server.core.settings import explain, load_settings, masked
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, Stop, TryEnd
from server.queue.redis import events as ev
from server.queue.render_try import Try
from tracer.radiosity import SolutionCache

log = logging.getLogger(__name__)

HOST = {"url": None, "device": "cpu", "threads": 1, "name": None, "host": socket.gethostname(), "cache": None}
DEFAULT_LOST_AFTER = 15.0
DEFAULT_CACHE_DIR = Path.home() / ".cache" / "raytrace-edu" / "radiosity"  # without --cache-dir, TRACER_CACHE_DIR
SETTINGS = ("redis_url", "redis_url_file", "render_threads", "cache_dir")  # Settings' fields the command line sets
HORSE_GRACE = 60  # s past an RQ job's timeout before its host gives up on it (RQ kills a forked horse then)
EXIT_STUCK = 70  # an in-process host's exit status when a try ran past that: a supervisor starts it afresh
SEND_RETRY_SECONDS = 60.0  # how long a try keeps sending its final event while Redis is unreachable
HORSE_STOP_GRACE = 20.0  # s a work horse has to give its try back once its host is stopping, before it is killed
HOST_CHECK = 0.5  # s between a work horse's looks at whether its host is still there


class Stopping:
    """Whether this host is stopping (in a work horse: whether its try is to give its job back), read by calling
    it. A plain flag, set by signal handlers: an Event's lock, taken again by a second signal's handler
    running inside the first one's, would hang the process for good."""

    def __init__(self) -> None:
        self.asked = False

    def set(self) -> None:
        self.asked = True

    def __call__(self) -> bool:
        return self.asked

    def wait(self, seconds: float) -> bool:
        """Sleep `seconds`, or less if asked to stop meanwhile; whether it was."""
        deadline = time.monotonic() + seconds
        while not self.asked and time.monotonic() < deadline:
            time.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
        return self.asked


STOP = Stopping()


def _redis(url: str) -> redis.Redis:
    return redis.Redis.from_url(url, socket_timeout=10, socket_connect_timeout=5, health_check_interval=5)


class RedisChannel:
    """A try's reports to the API through Redis (server/queue/render_try.py's Channel)."""

    def __init__(self, r: redis.Redis, job_id: str, attempt: int, snapshot_key: str | None = None):
        self.r, self.job_id, self.attempt, self.snapshot_key = r, job_id, attempt, snapshot_key
        self.files: dict[str, str] = {}  # JobFile value -> key, sent with the next event
        self.serial = 0
        self.bytes_sent = 0
        self.unreachable = 0  # reports that could not reach Redis (dropped, or retried for the final one)

    def _send(self, kind: ev.EventKind, **data) -> None:
        entry = ev.encode(kind, self.job_id, self.attempt, **data)
        fields: dict[FieldT, EncodableT] = {**entry}
        self.r.xadd(ev.STREAM, fields, maxlen=ev.STREAM_MAXLEN, approximate=True)
        self.bytes_sent += sum(len(v) for v in entry.values())

    def started(self, worker: str) -> None:
        self._send(ev.EventKind.started, host=HOST["host"], device=HOST["device"], worker=worker)

    def stop_reason(self) -> Stop | None:
        if STOP():
            return Stop.shutdown
        try:
            cancel, current, giveback = self.r.mget(
                ev.cancel_key(self.job_id), ev.try_key(self.job_id), ev.giveback_key(self.job_id, self.attempt)
            )
        except redis.RedisError:
            self.unreachable += 1
            return None  # cut off: render on; what it sends later is fenced if the job moved on meanwhile
        if cancel:
            return Stop.cancel
        if current is not None and int(current) != self.attempt:
            return Stop.lost
        if giveback:
            return Stop.shutdown
        return None

    def should_yield(self) -> bool:
        """Interactive work waits in its queue for more than a second (a free host would have taken it)."""
        try:
            first = self.r.lindex(Queue(ev.QUEUES[0], connection=self.r).key, 0)
            if first is None:
                return False
            enqueued = self.r.hget(f"rq:job:{ev.text(first)}", "enqueued_at")
        except redis.RedisError:
            return False
        if enqueued is None:
            return False
        when = datetime.fromisoformat(ev.text(enqueued).replace("Z", "+00:00"))
        if when.tzinfo is None:
            when = when.replace(tzinfo=UTC)
        return (datetime.now(UTC) - when).total_seconds() > 1.0

    def snapshot(self) -> bytes | None:
        if not self.snapshot_key:
            return None
        try:
            return cast(bytes | None, self.r.get(self.snapshot_key))  # (bytes: decode_responses is off)
        except redis.RedisError:
            return None

    def save(self, kind: JobFile, data: bytes | str) -> None:
        raw = data.encode() if isinstance(data, str) else data
        self.serial += 1
        key = ev.blob_key(self.job_id, self.attempt, self.serial)
        try:
            self.r.set(key, raw, ex=ev.BLOB_TTL)
        except redis.RedisError:
            self.unreachable += 1
            return
        self.bytes_sent += len(raw)
        self.files[JobFile(kind).value] = key

    def progress(self, **fields) -> None:
        try:
            self._send(ev.EventKind.progress, fields=fields, files=self.files)
            self.files = {}
        except redis.RedisError:
            self.unreachable += 1  # a later report carries the state again

    def finish(self, status: JobStatus, **fields) -> None:
        self._final(ev.EventKind.finish, status=JobStatus(status).value, fields=fields, files=self.files)

    def give_back(self, outcome: TryEnd = TryEnd.given_back, **fields) -> None:
        self._final(ev.EventKind.giveback, outcome=outcome, fields=fields, files=self.files)

    def _final(self, kind: ev.EventKind, **data) -> None:
        """The last word of a try: retried while Redis is unreachable (a cut cable may come back)."""
        deadline = time.monotonic() + SEND_RETRY_SECONDS
        while True:
            try:
                self._send(kind, **data)
                return
            except redis.RedisError:
                self.unreachable += 1
                if time.monotonic() > deadline:
                    log.warning("job %s try %d: Redis unreachable; its %s is lost", self.job_id, self.attempt, kind)
                    return
                time.sleep(1.0)


def run_try(payload: dict) -> dict:
    """The RQ job: one try of one job, in the work horse (forked from the worker, kernels loaded).
    `payload`: {job: {id, scene, max_seconds, samples_total, attempts}, limits: {...}, preview_interval}."""
    from rq import get_current_job

    from tracer.scene import Limits

    job = payload["job"]
    if os.getpid() != HOST["pid"]:
        _horse_watch(HOST["pid"])
    r = _redis(HOST["url"])
    channel = RedisChannel(r, job["id"], int(job["attempts"]), payload.get("snapshot_key"))
    rq_job = get_current_job()
    channel.started(HOST["name"] or (rq_job.worker_name if rq_job else None) or HOST["host"])
    limits = Limits(**payload["limits"])
    ended = Try(
        job, channel, limits, HOST["threads"], payload["preview_interval"], STOP, device=HOST["device"],
        cache=SolutionCache(HOST["cache"]), snapshot_interval=payload.get("snapshot_interval", 10.0),
    ).run()  # fmt: skip
    return {"ended": ended, "bytes_sent": channel.bytes_sent, "unreachable": channel.unreachable}


def _horse_watch(host: int) -> None:
    """In a forked work horse: its try gives its job back (STOP) on a SIGTERM of its own, or once its host is
    gone (killed with its process group, which the horse is not in)."""
    signal.signal(signal.SIGTERM, lambda signum, frame: STOP.set())

    def watch() -> None:
        while not STOP.wait(HOST_CHECK):
            if os.getppid() != host:
                log.warning("work horse %d: its worker host %d is gone; giving the try back", os.getpid(), host)
                STOP.set()

    threading.Thread(target=watch, name="host-watch", daemon=True).start()


def _ask_to_stop(signum, frame) -> None:
    """The host's handler of SIGTERM and SIGINT outside RQ's loop (waiting for Redis, starting a worker)."""
    STOP.set()


def _outside_rq() -> None:
    """This host's signal handlers, outside RQ's loop (which has its own: HostWorker.request_stop)."""
    signal.signal(signal.SIGTERM, _ask_to_stop)
    signal.signal(signal.SIGINT, _ask_to_stop)


class HostWorker(Worker):
    """RQ's forking worker, with heartbeats every `lost_after / 4` s that expire after `lost_after` s (RQ's
    own grace is a minute), this host's description in Redis, and a graceful stop that gives the try in
    hand back to the queue."""

    def __init__(self, *args, lost_after: float = DEFAULT_LOST_AFTER, **kwargs):
        self.lost_after = float(lost_after)
        self.stop_asked = time.monotonic()  # when the stop was asked (request_stop)
        self.giveback_sent = False
        kwargs.setdefault("job_monitoring_interval", max(1, int(self.lost_after / 4)))
        # RQ waits for work in blocks of worker_ttl - 15 seconds and beats its heart after each: twice
        # within lost_after, so an idle host never looks lost
        kwargs.setdefault("worker_ttl", 15 + max(1, int(self.lost_after / 2)))
        super().__init__(*args, **kwargs)

    def get_heartbeat_ttl(self, job, working_time: float = 0.0) -> int:
        return max(2, int(self.lost_after))

    def heartbeat(self, timeout: int | None = None, pipeline=None):
        super().heartbeat(timeout, pipeline)
        connection = pipeline if pipeline is not None else self.connection
        # RQ drops a worker from its registry when anyone lists the workers while its key is missing (a
        # host cut off long enough): every heartbeat registers it again, so a host that comes back is seen
        worker_registration.register(self, pipeline=pipeline)  # (None: the worker's connection)
        key = ev.host_key(self.name)
        mapping = {"host": HOST["host"], "device": HOST["device"], "threads": HOST["threads"]}
        connection.hset(key, mapping={**mapping, "lanes": ",".join(self.queue_names())})
        connection.expire(key, max(2, int(self.lost_after)))

    def _install_signal_handlers(self):
        super()._install_signal_handlers()
        if STOP():  # asked before RQ's handlers were there: stop before taking a try
            self._stop_requested = True

    def request_stop(self, signum, frame):
        """SIGTERM or Ctrl-C inside RQ's loop: the try in hand gives its job back (its work horse told by a
        signal of its own), then the loop ends; idle, it ends at once. RQ's own handler asks Redis whether the
        worker is busy, and waits on a Redis that has gone away; this one asks nothing, and takes no lock."""
        STOP.set()
        self.stop_asked = time.monotonic()
        self._shutdown_requested_date = now()  # a second signal (not one sent twice within a second) kills the try
        signal.signal(signal.SIGINT, self.request_force_stop)
        signal.signal(signal.SIGTERM, self.request_force_stop)
        if self.horse_pid:
            try:
                os.kill(self.horse_pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        if self.get_state() == WorkerStatus.BUSY:
            self._stop_requested = True  # RQ's loop ends once the try has ended
        else:
            raise StopRequested()  # out of RQ's wait for work

    def maintain_heartbeats(self, job, execution) -> None:
        """RQ's heartbeats while a try runs; once the host is stopping, the try's `giveback` key too (for a
        horse that missed its signal), and a horse not ended HORSE_STOP_GRACE s after the signal is killed."""
        if STOP() and self.horse_pid and time.monotonic() - self.stop_asked > HORSE_STOP_GRACE:
            log.warning("worker host %s: the work horse did not stop in %g s; killing it", self.name, HORSE_STOP_GRACE)
            self.kill_horse()
        if STOP() and not self.giveback_sent and (parsed := ev.parse_rq_job_id(job.id)) is not None:
            log.info("worker host %s: stopping; the try in hand gives its job back", self.name)
            self.connection.set(ev.giveback_key(*parsed), 1, ex=ev.FLAG_TTL)
            self.giveback_sent = True
        super().maintain_heartbeats(job, execution)


class InProcessWorker(HostWorker):
    """A host that runs each try in its own process, as RQ's SimpleWorker does: the class of a CUDA
    device's host (see the module's notes) and of `--no-fork`. What a forking worker does while its work
    horse renders, a thread does here: heartbeats every `lost_after / 4` s, so a long try is not lost; and
    if the try runs past its hard limit (RQ's timeout + HORSE_GRACE, where a forking worker kills its
    horse) the host exits with EXIT_STUCK: a render stuck in a GPU kernel cannot be interrupted any other
    way. The API has failed that job by then; the host's supervisor (systemd, a loop) starts it afresh."""

    def execute_job(self, job, queue) -> None:
        execution = self.prepare_execution(job)
        done = threading.Event()
        beats = threading.Thread(target=self._beat, args=(job, execution, done), name="heartbeat", daemon=True)
        beats.start()
        try:
            self.perform_job(job, queue, execution)
        finally:
            done.set()
            beats.join()
        self.set_state(WorkerStatus.IDLE)

    def _beat(self, job, execution, done: threading.Event) -> None:
        started = time.monotonic()
        limit = job.timeout + HORSE_GRACE if job.timeout and job.timeout > 0 else None
        while not done.wait(self.job_monitoring_interval):
            if limit is not None and time.monotonic() - started > limit:
                log.error("worker host %s: try %s still running after %.0f s; exiting", self.name, job.id, limit)
                logging.shutdown()
                os._exit(EXIT_STUCK)
            try:
                self.maintain_heartbeats(job, execution)
            except redis.RedisError as exc:  # cut off: the next beat tries again (or the try is lost)
                log.warning("worker host %s: heartbeat failed (%s)", self.name, exc)

    def kill_horse(self, sig=None) -> None:
        """No horse: the try runs in this process (RQ's Worker would signal the process group, its own)."""

    def wait_for_horse(self):
        return None, None, None


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
            r = _redis(url)
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
