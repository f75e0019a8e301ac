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
import threading
import time
from datetime import UTC, datetime
from typing import cast

import redis
from rq import Worker
from rq.job import Job

from server.core.credentials import masked
from server.jobs.lifecycle import JobStatus, Lane
from server.jobs.rows import JobRowWithScene
from server.queue.redis import events as ev
from server.queue.redis.consumer import EventConsumer
from server.queue.redis.monitor import Monitor

log = logging.getLogger(__name__)

WORKERS_SECONDS = 1.0  # how long the list of worker hosts read from Redis is kept (health, the lanes' capacity)


class RedisQueue(EventConsumer, Monitor):
    """The Redis backend (server/queue/base.py's JobQueue): its state and tries out (server/queue/redis/tries.py),
    its events in (consumer.py), its monitor and local worker hosts (monitor.py), and here its life and the API's
    calls."""

    backend = "redis"

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
