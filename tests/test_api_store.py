"""The job store alone: queue order, atomic claims, a dead worker's jobs, recovery after a restart."""

from __future__ import annotations

import json
import threading

import pytest

from server.models import JobStatus
from server.store import JobStore, QueueFull, looks_like_job_id


def add(store: JobStore, priority: int = 0, max_queued: int = 100) -> str:
    row = store.create(
        json.dumps({"camera": {}}), name=None, width=4, height=4, spp=1, priority=priority, warnings=[],
        max_seconds=60, max_queued=max_queued,
    )  # fmt: skip
    return row["id"]


def test_api_store_claims_by_priority_then_age(tmp_path):
    store = JobStore(tmp_path)
    a, b, c, d = add(store, 0), add(store, 5), add(store, 0), add(store, 5)
    order = [store.claim(pid=1)["id"] for _ in range(4)]
    assert order == [b, d, a, c]
    assert store.claim(pid=1) is None
    assert looks_like_job_id(a) and len({a, b, c, d}) == 4


def test_api_store_claims_are_atomic_across_threads(tmp_path):
    store = JobStore(tmp_path)
    ids = {add(store) for _ in range(40)}
    got, lock = [], threading.Lock()

    def claimer(pid: int) -> None:
        while (row := store.claim(pid)) is not None:
            with lock:
                got.append(row["id"])

    threads = [threading.Thread(target=claimer, args=(pid,)) for pid in range(1, 9)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(got) == sorted(ids)  # each job claimed exactly once


def test_api_store_queue_limit(tmp_path):
    store = JobStore(tmp_path)
    add(store, max_queued=2)
    add(store, max_queued=2)
    with pytest.raises(QueueFull):
        add(store, max_queued=2)
    assert store.counts()["queued"] == 2


def test_api_store_a_dead_worker_s_job_is_retried_then_failed(tmp_path):
    store = JobStore(tmp_path)
    job_id = add(store)
    assert store.claim(pid=11)["attempts"] == 1
    assert store.worker_died(11, attempts=2, reason="render worker killed") == [(job_id, "queued")]
    assert store.claim(pid=12)["attempts"] == 2
    assert not store.progress(job_id, 11, samples_done=5)  # the old worker no longer owns it
    assert store.worker_died(12, attempts=2, reason="render worker killed") == [(job_id, "failed")]
    row = store.get(job_id)
    assert row["status"] == JobStatus.failed and row["error"] == "render worker killed; tried 2 time(s)"


def test_api_store_recover_requeues_running_jobs(tmp_path):
    store = JobStore(tmp_path)
    running, cancelling, waiting = add(store), add(store), add(store)
    store.claim(pid=1)
    store.claim(pid=2)
    store.cancel(cancelling)
    assert store.recover() == (1, 1)
    again = JobStore(tmp_path)  # as a new server would open it
    assert [again.get(j)["status"] for j in (running, cancelling, waiting)] == ["queued", "cancelled", "queued"]
    assert again.claim(pid=3)["id"] == running  # it keeps its place in the queue


def test_api_store_one_server_per_data_directory(tmp_path):
    from server.main import lock_data_dir

    lock = lock_data_dir(tmp_path)
    with pytest.raises(RuntimeError, match="another server"):
        lock_data_dir(tmp_path)
    lock.close()
    lock_data_dir(tmp_path).close()
