"""The job store alone: queue order, atomic claims, a dead worker's jobs, recovery after a restart."""

from __future__ import annotations

import json
import threading

import pytest

from server.lifecycle import FINISHED, TRANSITIONS, BadTransition, JobStatus, check_transition
from server.store import AOV_NAMES, JobFile, JobStore, QueueFull, looks_like_job_id


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


def test_api_store_life_cycle_is_one_table():
    """Every status has its moves; the finished ones none (a finished job never moves again)."""
    assert set(TRANSITIONS) == set(JobStatus)
    assert FINISHED == {s for s in JobStatus if s.finished} == {s for s, moves in TRANSITIONS.items() if not moves}
    check_transition(JobStatus.queued, JobStatus.running)
    check_transition(JobStatus.running, JobStatus.queued)  # a worker stopping or dying gives it back
    for source, target in [("queued", "done"), ("done", "queued"), ("cancelled", "running"), ("failed", "failed")]:
        with pytest.raises(BadTransition):
            check_transition(JobStatus(source), JobStatus(target))


def test_api_store_moves_follow_the_life_cycle(tmp_path):
    store = JobStore(tmp_path)
    job_id = add(store)
    with pytest.raises(BadTransition):
        store.finish(job_id, None, JobStatus.queued)  # finish() only ends a job
    assert not store.finish(job_id, None, JobStatus.done)  # a queued job has no render to finish
    assert store.claim(pid=7)["status"] == "running"
    assert store.cancel(job_id)["status"] == "running"  # a running job is asked to stop, not ended
    assert store.fail(job_id, None, "over the time limit")  # the supervisor ends it first ...
    assert not store.finish(job_id, 7, JobStatus.cancelled, error="cancelled while rendering")  # ... so this is late
    row = store.get(job_id)
    assert (row["status"], row["error"]) == ("failed", "over the time limit") and row["finished_at"] is not None
    assert not store.requeue(job_id, 7) and store.get(job_id)["status"] == "failed"


def test_api_store_names_a_job_s_files(tmp_path):
    """The file layout of a job (DATA/jobs/<id>/) lives in the store: routes and workers ask it."""
    store = JobStore(tmp_path)
    job_id = add(store)
    assert store.job_file(job_id, JobFile.image("exr")) == tmp_path / "jobs" / job_id / "image.exr"
    assert AOV_NAMES == ("rays", "depth", "normal", "albedo", "variance")
    assert [store.job_file(job_id, JobFile.aov(n)).name for n in AOV_NAMES][:2] == ["aov_rays.png", "aov_depth.png"]
    with pytest.raises(ValueError):
        JobFile.aov("../image")  # only the names of the layout
    store.save_file(job_id, JobFile.aov_ranges, '{"rays": [1, 4]}')
    store.save_file(job_id, JobFile.image_png, b"\x89PNG")
    store.save_file(job_id, JobFile.radiosity, lambda tmp: tmp.write_text("{}"))
    assert sorted(p.name for p in store.job_dir(job_id).iterdir()) == ["aovs.json", "image.png", "radiosity.json"]
    assert json.loads(store.job_file(job_id, JobFile.aov_ranges).read_text()) == {"rays": [1, 4]}
    store.db.execute("UPDATE jobs SET status = 'done' WHERE id = ?", (job_id,))
    assert store.remove(job_id) and not store.job_dir(job_id).exists()


def test_api_store_one_server_per_data_directory(tmp_path):
    from server.main import lock_data_dir

    lock = lock_data_dir(tmp_path)
    with pytest.raises(RuntimeError, match="another server"):
        lock_data_dir(tmp_path)
    lock.close()
    lock_data_dir(tmp_path).close()


# -- the janitor ------------------------------------------------------------------------------

DAY = 86400.0
NOW = 1_900_000_000.0  # the present, for the janitor's rounds


def job_in(store: JobStore, status: str, ended: float | None = None, size: int = 1000) -> str:
    """A job in `status` that ended at `ended` (None: still queued/running), with `size` bytes of image."""
    job_id = add(store)
    store.db.execute("UPDATE jobs SET status = ?, finished_at = ? WHERE id = ?", (status, ended, job_id))
    folder = store.jobs_dir / job_id
    folder.mkdir()
    (folder / "image.png").write_bytes(b"x" * size)
    return job_id


def janitor(tmp_path, **settings):
    from server.janitor import Janitor
    from server.settings import Settings

    store = JobStore(tmp_path)
    return Janitor(Settings(data_dir=tmp_path, **settings), store), store


def test_api_store_janitor_removes_finished_jobs_past_their_time_only(tmp_path):
    jan, store = janitor(tmp_path, keep_finished="7d", max_data_bytes=0)
    old = {s: job_in(store, s, NOW - 8 * DAY) for s in ("done", "failed", "cancelled")}
    recent = job_in(store, "done", NOW - 6 * DAY)
    queued, running = job_in(store, "queued"), job_in(store, "running")
    store.db.execute("UPDATE jobs SET created_at = ? WHERE id IN (?, ?)", (NOW - 30 * DAY, queued, running))
    done = jan.clean(now=NOW)
    assert done.expired == 3 and done.for_size == 0
    for job_id in old.values():
        assert store.get(job_id) is None and not (store.jobs_dir / job_id).exists()  # row and folder together
    for job_id in (recent, queued, running):  # a queued or running job is never removed, however old
        assert store.get(job_id) is not None and (store.jobs_dir / job_id / "image.png").exists()
    assert jan.clean(now=NOW + 2 * DAY).expired == 1  # the recent one, in its turn


def test_api_store_janitor_keeps_everything_when_told_to(tmp_path):
    jan, store = janitor(tmp_path, keep_finished=0, max_data_bytes=0)
    job_id = job_in(store, "done", NOW - 1000 * DAY)
    assert jan.clean(now=NOW).expired == 0 and store.get(job_id) is not None


def test_api_store_janitor_caps_the_data_directory_oldest_finished_first(tmp_path, caplog):
    from server.janitor import GRACE, tree_size

    jan, store = janitor(tmp_path, keep_finished=0, max_data_bytes=0)
    first, second, third = (job_in(store, "done", NOW - (10 - k) * 3600, size=100_000) for k in range(3))
    running = job_in(store, "running", size=100_000)
    just_done = job_in(store, "failed", NOW - GRACE / 2, size=100_000)  # its client may still be reading it
    base = tree_size(tmp_path) - 5 * 100_000  # the database and the rest
    # room for three images: the two jobs that ended first go, the third stays
    jan.settings.max_data_bytes = base + 3 * 100_000 + 50_000
    done = jan.clean(now=NOW)
    assert done.for_size == 2 and done.size == tree_size(tmp_path) <= jan.settings.max_data_bytes
    gone = [store.get(j) is None for j in (first, second, third, running, just_done)]
    assert gone == [True, True, False, False, False]
    # room for one image only: all that may be removed is, and the rest is said once
    jan.settings.max_data_bytes = base + 100_000
    with caplog.at_level("WARNING", logger="server.janitor"):
        assert jan.clean(now=NOW).for_size == 1 and store.get(third) is None
        assert store.get(running) is not None and store.get(just_done) is not None
        jan.clean(now=NOW)
    assert caplog.text.count("no finished job is left to remove") == 1


def test_api_store_janitor_sweeps_folders_left_without_a_job(tmp_path):
    import os

    from server.janitor import GRACE

    jan, store = janitor(tmp_path, keep_finished="7d", max_data_bytes=0)
    kept = job_in(store, "done", NOW)
    orphan = store.jobs_dir / "AAAAAAAAAAAAAAAAAAAAAA"
    orphan.mkdir()
    (orphan / "image.png").write_bytes(b"x")
    fresh = store.jobs_dir / "BBBBBBBBBBBBBBBBBBBBBB"  # a folder being written right now: left alone
    fresh.mkdir()
    other = store.jobs_dir / "not a job"  # not a job id: never touched
    other.mkdir()
    for path in (orphan, store.jobs_dir / kept):
        os.utime(path, (NOW - 2 * GRACE, NOW - 2 * GRACE))
    os.utime(fresh, (NOW, NOW))
    assert jan.clean(now=NOW).orphans == 1
    assert not orphan.exists() and fresh.exists() and other.exists() and (store.jobs_dir / kept).exists()


def test_api_store_janitor_settings_read_durations_and_sizes(monkeypatch):
    from server.settings import Settings

    monkeypatch.setenv("TRACER_KEEP_FINISHED", "12h")
    monkeypatch.setenv("TRACER_MAX_DATA_BYTES", "2GiB")
    s = Settings()
    assert (s.keep_finished, s.max_data_bytes) == (43200.0, 2 * 1024**3)
    assert Settings(keep_finished="90", max_data_bytes="500MB").keep_finished == 90.0
    assert Settings(max_data_bytes="500MB").max_data_bytes == 500_000_000
    assert Settings(**s.model_dump(mode="json")).keep_finished == 43200.0  # as the workers receive them
    with pytest.raises(ValueError, match="30m, 12h, 7d"):
        Settings(keep_finished="a week")


def test_api_store_the_server_runs_the_janitor(tmp_path):
    """The app's lifespan starts the janitor: a job finished long ago is gone soon after start-up."""
    import time

    from fastapi.testclient import TestClient

    from server.main import create_app
    from server.settings import Settings

    store = JobStore(tmp_path)
    old = job_in(store, "done", time.time() - 30 * DAY)
    kept = job_in(store, "done", time.time() - DAY)
    settings = Settings(data_dir=tmp_path, workers=0, keep_finished="7d", janitor_interval=0.05)
    with TestClient(create_app(settings)) as client:
        deadline = time.monotonic() + 10
        while client.get(f"/api/jobs/{old}").status_code != 404:
            assert time.monotonic() < deadline, "the janitor did not remove the old job"
            time.sleep(0.05)
        assert client.get(f"/api/jobs/{kept}").status_code == 200
    assert not (tmp_path / "jobs" / old).exists()
