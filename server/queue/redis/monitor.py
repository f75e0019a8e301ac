"""The Redis backend's monitor (a mixin of RedisQueue, server/queue/redis/queue.py): a thread that, every second,
loses the tries whose worker host went silent or whose render process died, fails a try past its time limit,
queues every job again when Redis lost its data, and keeps the local worker hosts alive."""

from __future__ import annotations

import logging
import os
import secrets
import subprocess
import sys
import threading

import redis
from rq.job import Job
from rq.registry import StartedJobRegistry

from server.core.files import is_disk_full
from server.core.paths import ROOT
from server.jobs.lifecycle import JobStatus
from server.jobs.store_base import Attempt
from server.queue.redis import events as ev
from server.queue.redis.tries import HARD_GRACE, RedisTries

log = logging.getLogger(__name__)

MONITOR_INTERVAL = 1.0  # seconds between two rounds of the monitor
DIED_GRACE = 2.0  # seconds a dead render process's last events get to arrive before its try is lost
# seconds a try that RQ says finished may stay without its last word (done, failed) before it is lost: its
# events were sent to a Redis that died as it finished, while RQ wrote "finished" to the one that replaced it
FINISHED_GRACE = 10.0


class Monitor(RedisTries):
    """The monitor's rounds, and the local worker hosts it keeps."""

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
