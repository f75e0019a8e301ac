"""The Redis backend on a real redis-server and a job store on disk, with its clock in the test's hand: the
monitor losing tries (a try whose RQ job says it finished, but whose last word (done, failed) never came, is
lost after FINISHED_GRACE and queued again; a try still running is not), and the worker hosts read from Redis
at most once a second."""

from __future__ import annotations

import json

import pytest
from rq.job import Job

from server.core.settings import load_settings
from server.jobs.lifecycle import JobStatus
from server.jobs.store import JobStore
from server.queue.redis import events as ev
from server.queue.redis.monitor import FINISHED_GRACE
from server.queue.redis.queue import RedisQueue
from tests.support.api import Clock
from tests.support.queue import RedisServer
from tests.support.scene import scene_dict, small


@pytest.fixture
def queue(tmp_path):
    with RedisServer(tmp_path / "redis.log") as redis_server:
        settings = load_settings(data_dir=tmp_path / "data", redis_url=redis_server.url, workers=0)
        clock = Clock(1_000_000.0)
        q = RedisQueue(settings, JobStore(settings.data_dir), clock=clock)
        yield q, clock


def running_job(q: RedisQueue) -> str:
    """A job queued in the store and in RQ, whose try 1 a worker host took."""
    scene = small(scene_dict("whitted"), 8)
    row = q.store.create(json.dumps(scene), name=None, width=8, height=8, spp=1, priority=0, warnings=[],
                         max_seconds=60, max_queued=10)  # fmt: skip
    q.submitted(row)
    assert q.store.start_try(row["id"], 1, "host-a", "cpu", "w1") is not None
    return row["id"]


def rq_status(q: RedisQueue, job_id: str, attempt: int) -> bytes | None:
    return q.r.hget(Job.key_for(ev.rq_job_id(job_id, attempt)), "status")


def test_queue_redis_a_finished_try_without_its_last_word_runs_again(queue):
    q, clock = queue
    job_id = running_job(q)
    # RQ wrote "finished" (to a Redis that came back empty, say) while the try's done event went to the one that died
    q.r.hset(Job.key_for(ev.rq_job_id(job_id, 1)), "status", "finished")
    q._lost_tries()
    clock.now += FINISHED_GRACE - 0.5
    q._lost_tries()
    assert q.store.get(job_id)["status"] == JobStatus.running  # its last word may still be on the way
    clock.now += 1.0
    q._lost_tries()
    row = q.store.get(job_id)
    assert (row["status"], row["attempts"], row["lost"]) == (JobStatus.queued, 2, 1)
    assert rq_status(q, job_id, 2) == b"queued"  # try 2 is in RQ's queue for a host to take
    assert q.r.get(ev.try_key(job_id)) == b"2"  # and try 1's late events are stale


def test_queue_redis_a_try_still_running_is_not_lost(queue):
    q, clock = queue
    job_id = running_job(q)
    q.r.hset(Job.key_for(ev.rq_job_id(job_id, 1)), "status", "started")
    for _ in range(3):
        q._lost_tries()
        clock.now += 10 * FINISHED_GRACE
    row = q.store.get(job_id)
    assert (row["status"], row["attempts"], row["lost"]) == (JobStatus.running, 1, 0)


def test_queue_redis_the_worker_hosts_are_read_from_redis_once_a_second(queue):
    """GET /api/health lists the worker hosts: 100 answers within a second read them from Redis once, each gets
    dicts of its own (health blanks another token's job in them), and a second later they are read again."""
    q, clock = queue
    reads, read = [], q._read_workers
    q._read_workers = lambda: reads.append(clock.now) or [{"name": "host-a", "job": "j1", "lanes": ["batch"]}]
    seen = [q.workers() for _ in range(100)]
    seen[0][0]["job"] = None
    assert len(reads) == 1 and q.workers()[0]["job"] == "j1"
    clock.now += 0.9
    q.workers()
    assert len(reads) == 1
    clock.now += 0.2
    q.workers()
    assert len(reads) == 2
    q._read_workers = read
    clock.now += 2
    assert q.workers() == []  # the real read: no host has registered with this Redis
