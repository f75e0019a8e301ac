"""The Redis backend's API side: jobs out to worker hosts through RQ, their events back into the store.

- `submitted`: the job's first try goes to RQ (RQ job `<id>-try1`); the store records which try is out.
- A consumer thread reads the worker hosts' events (server/queue/redis/events.py) in a consumer group and
  applies each to the store, fenced by its try: files into the job's folder, then the row.
- A monitor thread, every second:
  - finds the tries whose worker host stopped sending heartbeats (RQ's started registry: the
    entry expires `lost_after` seconds after the last one), or whose render process died, and
    queues the job's next try (`job_attempts` lost tries fail it);
  - fails a try past its time limit (and tells its host to stop);
  - notices when Redis lost its data (restart, flush: the epoch key is gone) and queues again
    every queued and running job the store has;
  - keeps the local worker hosts alive (`workers` > 0: `python -m server.worker` processes).
- `cancelled`: a flag every host checks between bands; a queued try is taken out of RQ too.

While the API's disk is full an event is not acknowledged: it is read and applied again every few
seconds until it can be written (a full disk loses no progress, image or end of a job).

One lock serialises every change the API makes to a job of this backend (applying an event,
losing a try, a cancel), so a try is never both applied and lost.
"""

from __future__ import annotations

import logging
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import cast

import redis
from rq import Queue, Worker
from rq.job import Job
from rq.registry import StartedJobRegistry

from server.core.files import is_disk_full
from server.core.paths import ROOT
from server.core.settings import Settings, masked
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobStatus, Lane, TryEnd
from server.jobs.rows import JobRow, JobRowWithScene
from server.jobs.store import JobStore
from server.jobs.store_base import Attempt
from server.queue.redis import events as ev

log = logging.getLogger(__name__)

MONITOR_INTERVAL = 1.0  # seconds between two rounds of the monitor
HARD_GRACE = 10.0  # seconds past a try's time limit before the API fails it (its host stops it itself at the limit)
DISK_FULL_PAUSE = 2.0  # seconds between two tries to apply an event while the data directory's disk is full
DIED_GRACE = 2.0  # seconds a dead render process's last events get to arrive before its try is lost
# seconds a try that RQ says finished may stay without its last word (done, failed) before it is lost: its
# events were sent to a Redis that died as it finished, while RQ wrote "finished" to the one that replaced it
FINISHED_GRACE = 10.0
WORKERS_SECONDS = 1.0  # how long the list of worker hosts read from Redis is kept (health, the lanes' capacity)

# XREADGROUP's reply on a connection that answers bytes: [(stream, [(entry id, {field: value}), ...])], or
# None when nothing came within the block
StreamReply = list[tuple[bytes, list[tuple[bytes, dict[bytes, bytes]]]]] | None


class RedisQueue:
    backend = "redis"

    def __init__(
        self,
        settings: Settings,
        store: JobStore,
        stopping: Callable[[], bool] = lambda: False,
        clock: Callable[[], float] = time.time,
    ):
        self.settings, self.store = settings, store
        self.clock = clock  # the wall clock of the monitor's graces and time limits (a test's own)
        self.stopping = stopping  # the server has been asked to stop: its local worker hosts are not restarted
        assert settings.redis_url is not None  # (make_queue picks this backend for a Redis URL)
        self.url: str = settings.redis_url
        self.r = redis.Redis.from_url(self.url, socket_timeout=10, socket_connect_timeout=5, health_check_interval=5)
        self.queues = {name: Queue(name, connection=self.r) for name in ev.QUEUES}
        self.lock = threading.RLock()
        self.stop = threading.Event()
        self.threads: list[threading.Thread] = []
        self.consumer = "api"  # one API per Redis: the same name after a restart finds what it had not acknowledged
        self.epoch: bytes | None = None
        self._workers: tuple[float, list[dict]] | None = None  # (when, the worker hosts) as last read from Redis
        self.died_since: dict[str, float] = {}  # rq id -> when its render process was first seen dead
        self.hosts: list[subprocess.Popen | None] = [None] * settings.workers
        self.stats = {"events": 0, "stale": 0, "bytes": 0, "lost": 0}
        self.unsent = False  # a job was queued in the store while Redis was unreachable: the monitor sends it

    # -- life ---------------------------------------------------------------------------------

    def start(self, kernels: threading.Event | None = None) -> None:
        self._hold_api_mark()
        self.r.hset(ev.CONFIG, mapping={"lost_after": self.settings.lost_after})
        self._ensure_group()
        self.epoch = cast(bytes | None, self.r.get(ev.EPOCH))  # (bytes: decode_responses is off)
        if self.epoch is None:
            self.epoch = secrets.token_hex(8).encode()
            self.r.set(ev.EPOCH, self.epoch)
        self._requeue_missing()
        for target, name in ((self._consume, "events"), (self._monitor, "monitor")):
            t = threading.Thread(target=target, name=f"rq-{name}", daemon=True)
            t.start()
            self.threads.append(t)
        if kernels is None:
            self._start_hosts()
        else:  # once the server has the kernels in Warp's cache: the hosts then read it
            t = threading.Thread(target=self._start_hosts, args=(kernels,), name="rq-hosts", daemon=True)
            t.start()
            self.threads.insert(0, t)  # joined first at shutdown, before the hosts are stopped
        log.info("job queue: Redis at %s (%d local worker host(s))", masked(self.url), len(self.hosts))

    def _hold_api_mark(self) -> None:
        """One API per Redis database (two would split the events between them): wait for the mark of a
        stopped API to expire, refuse to start beside a live one."""
        self.mark = f"{os.uname().nodename}:{os.getpid()}:{self.settings.data_dir.resolve()}"
        deadline = time.monotonic() + ev.API_TTL + 1
        while not self.r.set(ev.API, self.mark, nx=True, ex=ev.API_TTL):
            if time.monotonic() > deadline:
                other = ev.text(cast(bytes | None, self.r.get(ev.API)) or b"?")
                raise RuntimeError(
                    f"another API uses this Redis database ({other}); give each API its own database "
                    "(redis://host:6379/N) or Redis"
                )
            time.sleep(0.5)

    def shutdown(self) -> None:
        self.stop.set()
        if self.threads and self.threads[0].name == "rq-hosts":
            self.threads[0].join(timeout=5)  # no host started after the ones stopped here
        for p in self.hosts:
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGTERM)  # the try in hand gives its job back
        for p in self.hosts:
            if p is not None:
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait(timeout=5)
        for t in self.threads:
            t.join(timeout=5)
        try:
            if self.r.get(ev.API) == self.mark.encode():
                self.r.delete(ev.API)
        except redis.RedisError:
            pass
        self.r.close()

    # -- the API's calls ----------------------------------------------------------------------

    def submitted(self, row: JobRowWithScene) -> None:
        with self.lock:
            try:
                self._enqueue(row, 1)
            except redis.RedisError as exc:  # the job is queued in the store: it goes out once Redis answers
                self.unsent = True
                log.warning("job %s: Redis unreachable (%s); it is queued here and goes out when Redis is back",
                            row["id"], exc)  # fmt: skip

    def cancelled(self, row: JobRowWithScene) -> None:
        with self.lock:
            self.r.set(ev.cancel_key(row["id"]), 1, ex=ev.FLAG_TTL)
            if row["status"] == JobStatus.cancelled:  # it was queued: take its try out of RQ
                try:
                    Job.fetch(ev.rq_job_id(row["id"], max(1, row["attempts"])), connection=self.r).cancel()
                except Exception:  # gone already (a worker took it: it sees the flag)
                    pass

    def workers(self) -> list[dict]:
        """The worker hosts with a recent heartbeat, as read from Redis at most once in WORKERS_SECONDS (health is
        asked often: by monitors, and by every page that shows the queue); each call gets its own dicts."""
        now = self.clock()
        kept = self._workers
        if kept is None or not 0 <= now - kept[0] < WORKERS_SECONDS:
            kept = self._workers = (now, self._read_workers())
        return [dict(w) for w in kept[1]]

    def _read_workers(self) -> list[dict]:
        """The worker hosts with a recent heartbeat (RQ's worker registry, and each host's description)."""
        out = []
        now = datetime.now(UTC)
        for w in sorted(Worker.all(connection=self.r), key=lambda w: w.name):
            beat = w.last_heartbeat
            if beat is not None and beat.tzinfo is None:
                beat = beat.replace(tzinfo=UTC)
            alive = beat is not None and (now - beat).total_seconds() <= self.settings.lost_after + 1
            if not alive:
                continue
            info = {ev.text(k): ev.text(v) for k, v in self.r.hgetall(ev.host_key(w.name)).items()}
            current = w.get_current_job_id()
            parsed = ev.parse_rq_job_id(current) if current else None
            out.append(
                {
                    "slot": len(out),
                    "name": w.name,
                    "host": info.get("host") or w.hostname,
                    "device": info.get("device"),
                    "threads": int(info["threads"]) if info.get("threads") else None,
                    "pid": w.pid,
                    "alive": True,
                    "ready": True,
                    "restarts": 0,
                    "job": parsed[0] if parsed else None,
                    "lanes": (info.get("lanes") or ",".join(ev.QUEUES)).split(","),
                }
            )
        return out

    def capacity(self, lane: Lane) -> int:
        return sum(1 for w in self.workers() if str(lane) in w["lanes"])

    # -- out: tries into RQ -------------------------------------------------------------------

    def _row(self, job_id: str) -> JobRowWithScene:
        """The row of a job that is there: queued or running (a job's row goes only after it finished)."""
        row = self.store.get(job_id)
        assert row is not None
        return row

    def _enqueue(self, row: JobRowWithScene, attempt: int) -> None:
        """Put try `attempt` of a queued job into RQ (the store records it first)."""
        job_id = row["id"]
        self.store.queue_try(job_id, attempt)
        self.r.set(ev.try_key(job_id), attempt, ex=ev.FLAG_TTL)
        job = {k: row[k] for k in ("id", "kind", "lane", "params", "scene", "max_seconds", "samples_total")}
        job.update(attempts=attempt, snapshot=row["snapshot"], preview=row["preview"])
        payload = {
            "job": job,
            "limits": {k: getattr(self.settings.limits, k) for k in self.settings.limits.__dataclass_fields__},
            "preview_interval": self.settings.preview_interval,
            "snapshot_interval": self.settings.snapshot_interval,
        }
        if row["snapshot"]:  # the film to continue from travels with the try
            try:
                data = self.store.job_file(job_id, JobFile.snapshot).read_bytes()
            except OSError:
                job["snapshot"] = 0
            else:
                key = ev.snapshot_key(job_id, attempt)
                self.r.set(key, data, ex=ev.BLOB_TTL)
                payload["snapshot_key"] = key
        self.queues[row["lane"]].enqueue_call(
            "server.queue.redis.host.run_try",
            kwargs={"payload": payload},
            job_id=ev.rq_job_id(job_id, attempt),
            timeout=int(row["max_seconds"] + 2 * HARD_GRACE),
            result_ttl=600,
            failure_ttl=24 * 3600,
            at_front=row["priority"] > 0,
            description=f"render job {job_id} try {attempt}",
        )

    def _requeue_missing(self) -> None:
        """Every queued job whose try is not in Redis (the API stopped before it went out, or Redis lost
        it) goes out again; running ones whose try Redis no longer knows run again as the next try."""
        with self.lock:
            for row in self.store.live_tries():
                attempt = max(1, row["attempts"])
                if self.r.exists(Job.key_for(ev.rq_job_id(row["id"], attempt))):
                    continue
                full = self._row(row["id"])
                if row["status"] == JobStatus.queued:
                    self._enqueue(full, attempt)
                elif self.store.requeue(row["id"], Attempt(attempt)) == JobStatus.queued:  # not counted as lost
                    self._enqueue(self._row(row["id"]), attempt + 1)
                    log.warning("job %s: its try %d is gone from Redis; queued again", row["id"], attempt)

    # -- in: events into the store ------------------------------------------------------------

    def _ensure_group(self) -> None:
        try:
            self.r.xgroup_create(ev.STREAM, ev.GROUP, id="0", mkstream=True)
        except redis.ResponseError as exc:
            if "BUSYGROUP" not in str(exc):
                raise

    def _consume(self) -> None:
        pending = True  # first the entries delivered to this consumer before and not acknowledged
        while not self.stop.is_set():
            try:
                got = cast(
                    StreamReply,
                    self.r.xreadgroup(
                        ev.GROUP, self.consumer, {ev.STREAM: "0" if pending else ">"}, count=100, block=500
                    ),
                )
                entries = got[0][1] if got else []
                if pending and not entries:
                    pending = False
                    continue
                for entry_id, fields in entries:
                    self._apply_entry(fields)
                    self.r.xack(ev.STREAM, ev.GROUP, entry_id)
            except redis.ResponseError as exc:
                if "NOGROUP" in str(exc):  # Redis lost its data: the monitor queues the jobs again
                    self._ensure_group()
                    pending = True
                else:
                    log.exception("reading the worker hosts' events")
                    self.stop.wait(1.0)
            except redis.RedisError as exc:
                log.warning("Redis unreachable while reading events (%s); retrying", exc)
                self.stop.wait(1.0)
            except Exception as exc:
                if is_disk_full(exc):  # not acknowledged: read again (every event applies twice harmlessly)
                    log.warning("the disk is full: a worker host's event waits to be applied (%s)", exc)
                    pending = True
                    self.stop.wait(DISK_FULL_PAUSE)
                    continue
                log.exception("applying a worker host's event")
                self.stop.wait(0.2)

    def _apply_entry(self, fields: dict) -> None:
        kind, job_id, attempt, data = ev.decode(fields)
        self.stats["events"] += 1
        with self.lock:
            row = self.store.get(job_id)
            if kind == ev.EventKind.started:
                if self.store.start_try(job_id, attempt, data.get("host"), data.get("device"), data.get("worker")):
                    return
                log.info("job %s: try %d started, but the job has moved on (%s)", job_id, attempt, _state(row))
                return
            current = row is not None and row["status"] == JobStatus.running and row["attempts"] == attempt
            files = data.get("files") or {}
            if not current:  # a stale try (lost, or the job was cancelled or ended): nothing of it lands
                self.stats["stale"] += 1
                if files:
                    self.r.delete(*files.values())
                log.info("job %s: %s of try %d dropped (%s)", job_id, kind, attempt, _state(row))
                return
            self._copy_files(job_id, files)
            fence = Attempt(attempt)
            if kind == ev.EventKind.progress:
                self.store.progress(job_id, fence, **data.get("fields", {}))
            elif kind == ev.EventKind.finish:
                self.store.finish(job_id, fence, JobStatus(data["status"]), **data.get("fields", {}))
                self.r.delete(ev.try_key(job_id), ev.cancel_key(job_id))
            elif kind == ev.EventKind.giveback:
                if data.get("fields"):
                    self.store.progress(job_id, fence, **data["fields"])
                outcome = TryEnd(data.get("outcome") or TryEnd.given_back)
                moved = self.store.requeue(job_id, fence, outcome)
                if moved == JobStatus.queued:
                    self._enqueue(self._row(job_id), attempt + 1)
                    log.info("job %s: try %d %s; queued as try %d", job_id, attempt, outcome, attempt + 1)
                elif moved == JobStatus.cancelled:  # its cancel was accepted while it ran: it ends here
                    self.r.delete(ev.try_key(job_id), ev.cancel_key(job_id))

    def _copy_files(self, job_id: str, files: dict[str, str]) -> None:
        if not files:
            return
        keys = list(files.values())
        blobs = self.r.mget(keys)
        for name, blob in zip(files, blobs, strict=True):
            if blob is None:
                log.warning("job %s: the file %s it sent has expired from Redis", job_id, name)
                continue
            self.stats["bytes"] += len(blob)
            self.store.save_file(job_id, JobFile(name), blob)
        self.r.delete(*keys)

    # -- the monitor --------------------------------------------------------------------------

    def _monitor(self) -> None:
        while not self.stop.wait(MONITOR_INTERVAL):
            try:
                self.r.set(ev.API, self.mark, ex=ev.API_TTL)
                self._check_epoch()
                if self.unsent:
                    with self.lock:  # raises while Redis is still away: the next round tries again
                        self._requeue_missing()
                        self.unsent = False
                self._lost_tries()
                self._overdue()
                self._keep_hosts()
            except redis.RedisError as exc:
                log.warning("Redis unreachable (%s); the monitor retries", exc)
            except Exception as exc:
                if is_disk_full(exc):
                    log.warning("job queue monitor: the disk is full (%s)", exc)
                else:
                    log.exception("job queue monitor")

    def _check_epoch(self) -> None:
        if self.r.get(ev.EPOCH) == self.epoch:
            return
        log.warning("Redis lost its data (restarted or flushed): queuing every queued and running job again")
        self.r.hset(ev.CONFIG, mapping={"lost_after": self.settings.lost_after})
        self._ensure_group()
        self.epoch = secrets.token_hex(8).encode()
        self.r.set(ev.EPOCH, self.epoch)
        self._requeue_missing()

    def _lost_tries(self) -> None:
        """Tries whose host stopped its heartbeats (an expired entry in RQ's started registry), or whose
        render process died (RQ marked it failed or stopped without a last word from the try)."""
        registries = [StartedJobRegistry(name, connection=self.r) for name in ev.QUEUES]
        now = self.clock()
        expired = {rq_id for registry in registries for rq_id in registry.get_expired_job_ids(now)}
        for row in self.store.live_tries():
            rq_id = ev.rq_job_id(row["id"], max(1, row["attempts"]))
            reason = None
            if rq_id in expired:
                reason = f"its worker host sent no heartbeat for {self.settings.lost_after:g} s"
            elif row["status"] == JobStatus.running:
                status = self.r.hget(Job.key_for(rq_id), "status")
                if status in (b"failed", b"stopped", b"canceled", b"finished"):
                    first = self.died_since.setdefault(rq_id, now)
                    if now - first >= (FINISHED_GRACE if status == b"finished" else DIED_GRACE):
                        reason = f"its render process on the worker host ended without a word ({status.decode()})"
            if reason is not None:
                self._lose(row["id"], max(1, row["attempts"]), reason)
                self.died_since.pop(rq_id, None)
        if expired:
            for registry in registries:
                registry.cleanup(now)  # RQ moves them to its failed registry: not seen again

    def _lose(self, job_id: str, attempt: int, reason: str) -> None:
        with self.lock:
            moved = self.store.lose_try(job_id, attempt, reason, self.settings.job_attempts)
            if moved is None:
                return
            self.stats["lost"] += 1
            status, next_attempt = moved
            if status == JobStatus.queued:
                self._enqueue(self._row(job_id), next_attempt)
                log.warning("job %s: try %d lost (%s); queued as try %d", job_id, attempt, reason, next_attempt)
            else:
                self.r.delete(ev.try_key(job_id))
                log.warning("job %s: try %d lost (%s); the job is %s", job_id, attempt, reason, status)

    def _overdue(self) -> None:
        now = self.clock()
        for row in self.store.live_tries():
            if row["status"] != JobStatus.running or row["started_at"] is None:
                continue
            if now > row["started_at"] + row["max_seconds"] + HARD_GRACE:
                limit = row["max_seconds"]
                error = f"stopped: over the time limit of {limit:g} s per job (TRACER_MAX_JOB_SECONDS)"
                with self.lock:
                    if self.store.finish(row["id"], Attempt(row["attempts"]), JobStatus.failed, error=error):
                        self.r.set(ev.cancel_key(row["id"]), 1, ex=ev.FLAG_TTL)  # its host stops rendering it
                        log.warning("job %s: over its time limit on its worker host; failed", row["id"])

    # -- local worker hosts -------------------------------------------------------------------

    def _start_hosts(self, kernels: threading.Event | None = None) -> None:
        while kernels is not None and not kernels.wait(0.5):
            if self.stop.is_set() or self.stopping():
                return
        for slot in range(len(self.hosts)):
            if not self.stop.is_set() and not self.stopping():
                self._start_host(slot)

    def _start_host(self, slot: int) -> None:
        cmd = [sys.executable, "-m", "server.worker", "--name", f"{os.uname().nodename}.api{slot}"]
        if self.settings.render_threads:
            cmd += ["--threads", str(self.settings.render_threads)]
        env = {k: v for k, v in os.environ.items() if k != "TRACER_REDIS_URL_FILE"}
        env["TRACER_REDIS_URL"] = self.url  # in its environment, not on its command line (which ps shows)
        self.hosts[slot] = host = subprocess.Popen(cmd, cwd=ROOT, env=env)
        log.info("started local worker host %d (pid %d)", slot, host.pid)

    def _keep_hosts(self) -> None:
        for slot, p in enumerate(self.hosts):
            if p is not None and p.poll() is not None and not self.stop.is_set() and not self.stopping():
                log.warning("local worker host %d exited with %s; starting it again", slot, p.returncode)
                self._start_host(slot)


def _state(row: JobRow | None) -> str:
    if row is None:
        return "the job is gone"
    return f"the job is {row['status']} on try {row['attempts']}"
