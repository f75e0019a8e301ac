"""The RQ workers of a Redis worker host (server/queue/redis/host.py runs one): `HostWorker`, RQ's forking
worker, and `InProcessWorker`, which runs each try in the host's own process.

On a CUDA device (`--device cuda:0`) nothing forks: CUDA does not survive a fork (a child forked
after CUDA was initialised cannot use it), and initialising CUDA afresh in every work horse would cost
more than a GPU render. So a GPU host initialises CUDA and loads the kernels once, in its one process,
and runs each try there (`InProcessWorker`, RQ's SimpleWorker with this host's heartbeats); the CUDA
context stays warm from try to try. `--no-fork` picks that class on the CPU too (the tests use it).

Heartbeats: the RQ worker refreshes its try's entry in RQ's started registry every
`lost_after / 4` seconds with an expiry of `lost_after` (the API's setting, read from Redis), so a
host that dies or is cut off loses its try after `lost_after` seconds: the API finds the expired
entry and queues the job's next try for another host.

Stopping inside RQ's loop (SIGTERM or Ctrl-C): the host passes the signal to its work horse (which RQ puts in a
process group of its own, so a signal to the host's group misses it); a horse that has not ended
`HORSE_STOP_GRACE` seconds later is killed, and a second signal kills it at once.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time

import redis
from rq import Worker, worker_registration
from rq.exceptions import StopRequested
from rq.utils import now
from rq.worker import WorkerStatus

from server.queue.redis import events as ev
from server.queue.redis.horse import HOST, STOP

log = logging.getLogger(__name__)

DEFAULT_LOST_AFTER = 15.0
HORSE_GRACE = 60  # s past an RQ job's timeout before its host gives up on it (RQ kills a forked horse then)
EXIT_STUCK = 70  # an in-process host's exit status when a try ran past that: a supervisor starts it afresh
HORSE_STOP_GRACE = 20.0  # s a work horse has to give its try back once its host is stopping, before it is killed


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

    def unsubscribe(self) -> None:
        """RQ's, told to its listening thread first. That thread reads the host's channel in blocks of 60 s, and
        RQ tells it to end only after sending UNSUBSCRIBE: where the reply to that came first (a loaded machine;
        the GIL to the reading thread), the thread read on, and the stop waited out its block (a host asked to
        stop took 30 s and more, until its supervisor killed it). Told first, it ends at that reply."""
        thread = self.pubsub_thread
        if thread is not None:
            thread.stop(timeout=0)  # its loop ends at the next message it reads (no wait here)
        try:
            super().unsubscribe()
        except redis.ConnectionError:  # the thread, between two reads when told, closed the connection first
            pass

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
