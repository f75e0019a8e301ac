"""The job store alone (server/jobs/): queue order, atomic claims, a dead worker's jobs,
recovery after a restart, the moves of the life cycle, a job's files."""

from __future__ import annotations

import json
import threading

import pytest

from server.core.ids import looks_like_job_id
from server.jobs.files import AOV_NAMES, JobFile
from server.jobs.lifecycle import FINISHED, TRANSITIONS, BadTransition, JobStatus, Lane, check_transition
from server.jobs.rows import JobRow, JobRowWithScene
from server.jobs.store import JobStore, QueueFull
from tests.support.store import add


def test_store_claims_by_priority_then_age(tmp_path):
    store = JobStore(tmp_path)
    a, b, c, d = add(store, 0), add(store, 5), add(store, 0), add(store, 5)
    order = [store.claim(pid=1)["id"] for _ in range(4)]
    assert order == [b, d, a, c]
    assert store.claim(pid=1) is None
    assert looks_like_job_id(a) and len({a, b, c, d}) == 4


def test_store_place_counts_the_jobs_ahead_and_never_the_job_itself(tmp_path):
    """A queued job's place: the queued jobs a worker takes first and the running ones it waits for, with
    their estimates; a job that a worker took after its row was read is not waiting for itself."""
    store = JobStore(tmp_path)

    def job(lane: Lane, estimate: float, priority: int = 0) -> dict:
        return store.create(json.dumps({"camera": {}}), name=None, width=4, height=4, spp=1, priority=priority,
                            warnings=[], max_seconds=60, max_queued=100, lane=lane, estimate=estimate)  # fmt: skip

    busy = job(Lane.batch, 100.0)
    assert store.claim(pid=1)["id"] == busy["id"]
    first, second, late = job(Lane.interactive, 2.0), job(Lane.interactive, 3.0), job(Lane.batch, 7.0)
    assert store.place(first) == {"ahead": 0, "ahead_seconds": 0, "running": 0, "running_seconds": 0}
    assert store.place(second) == {"ahead": 1, "ahead_seconds": 2.0, "running": 0, "running_seconds": 0}
    # a batch job waits for every queued interactive job and for the running batch render
    assert store.place(late) == {"ahead": 2, "ahead_seconds": 5.0, "running": 1, "running_seconds": 100.0}
    assert store.claim(pid=2)["id"] == first["id"]  # taken after `first` was read as queued
    assert store.place(first)["running"] == 0
    assert store.place(second) == {"ahead": 0, "ahead_seconds": 0, "running": 1, "running_seconds": 2.0}


def test_store_claims_are_atomic_across_threads(tmp_path):
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


def test_store_queue_limit(tmp_path):
    store = JobStore(tmp_path)
    add(store, max_queued=2)
    add(store, max_queued=2)
    with pytest.raises(QueueFull):
        add(store, max_queued=2)
    assert store.counts()["queued"] == 2


def test_store_queue_limit_per_owner(tmp_path):
    store = JobStore(tmp_path)

    def add_owned(owner: str | None) -> str:
        return store.create("{}", name=None, width=2, height=2, spp=1, priority=0, warnings=[], max_seconds=60,
                            max_queued=100, owner=owner, max_queued_owner=2)["id"]  # fmt: skip

    add_owned("a" * 64)
    first = add_owned("a" * 64)
    with pytest.raises(QueueFull) as full:
        add_owned("a" * 64)
    assert full.value.args == (2, "owner")
    add_owned("b" * 64)  # another owner has a share of their own
    add_owned(None)  # the instructor's jobs have no share
    store.cancel(first)
    add_owned("a" * 64)  # a place of one's own freed: one more
    assert store.counts()["queued"] == 4


def test_store_a_dead_worker_s_job_is_retried_then_failed(tmp_path):
    store = JobStore(tmp_path)
    job_id = add(store)
    assert store.claim(pid=11)["attempts"] == 1
    assert store.worker_died(11, max_tries=2, reason="render worker killed") == [(job_id, "queued")]
    assert store.claim(pid=12)["attempts"] == 2
    assert not store.progress(job_id, 11, samples_done=5)  # the old worker no longer owns it
    assert store.worker_died(12, max_tries=2, reason="render worker killed") == [(job_id, "failed")]
    row = store.get(job_id)
    assert row["status"] == JobStatus.failed
    assert row["error"] == "render worker killed; tried 2 time(s)"


def test_store_a_try_put_back_by_a_restart_is_not_a_lost_one(tmp_path):
    """A job running when its server stopped is queued again at the next start (`recover`): that try was not
    lost with its worker, so one death after it still gets the job its retry (one rule for both backends:
    lifecycle.after_lost counts the tries lost, never the tries taken)."""
    store = JobStore(tmp_path)
    job_id = add(store)
    store.claim(pid=11)
    assert store.recover() == (1, 0)
    assert store.claim(pid=12)["attempts"] == 2
    assert store.worker_died(12, max_tries=2, reason="render worker killed") == [(job_id, "queued")]
    assert store.claim(pid=13)["attempts"] == 3
    assert store.worker_died(13, max_tries=2, reason="render worker killed") == [(job_id, "failed")]
    assert store.get(job_id)["lost"] == 2


def test_store_lifecycle_after_lost_is_the_rule_of_both_backends():
    from server.jobs.lifecycle import after_lost

    assert [after_lost(lost, 2, False) for lost in (0, 1, 2)] == [JobStatus.queued, JobStatus.failed, JobStatus.failed]
    assert after_lost(0, 2, True) is JobStatus.cancelled


def test_store_recover_requeues_running_jobs(tmp_path):
    store = JobStore(tmp_path)
    running, cancelling, waiting = add(store), add(store), add(store)
    store.claim(pid=1)
    store.claim(pid=2)
    store.cancel(cancelling)
    assert store.recover() == (1, 1)
    again = JobStore(tmp_path)  # as a new server would open it
    assert [again.get(j)["status"] for j in (running, cancelling, waiting)] == ["queued", "cancelled", "queued"]
    assert again.claim(pid=3)["id"] == running  # it keeps its place in the queue


def test_store_life_cycle_is_one_table():
    """Every status has its moves; the finished ones none (a finished job never moves again)."""
    assert set(TRANSITIONS) == set(JobStatus)
    assert FINISHED == {s for s in JobStatus if s.finished} == {s for s, moves in TRANSITIONS.items() if not moves}
    check_transition(JobStatus.queued, JobStatus.running)
    check_transition(JobStatus.running, JobStatus.queued)  # a worker stopping or dying gives it back
    for source, target in [("queued", "done"), ("done", "queued"), ("cancelled", "running"), ("failed", "failed")]:
        with pytest.raises(BadTransition):
            check_transition(JobStatus(source), JobStatus(target))


def test_store_moves_follow_the_life_cycle(tmp_path):
    store = JobStore(tmp_path)
    job_id = add(store)
    with pytest.raises(BadTransition):
        store.finish(job_id, None, JobStatus.queued)  # finish() only ends a job
    assert not store.finish(job_id, None, JobStatus.done)  # a queued job has no render to finish
    assert store.claim(pid=7)["status"] == "running"
    assert store.fail(job_id, None, "over the time limit")  # the supervisor ends it first ...
    assert not store.finish(job_id, 7, JobStatus.cancelled, error="cancelled while rendering")  # ... so this is late
    row = store.get(job_id)
    assert (row["status"], row["error"]) == ("failed", "over the time limit")
    assert row["finished_at"] is not None
    assert not store.requeue(job_id, 7) and store.get(job_id)["status"] == "failed"
    assert store.cancel(job_id)["status"] == "failed"  # an ended job: the cancel changes nothing


@pytest.mark.parametrize(
    "end, error",
    [
        (lambda s, j: s.finish(j, 7, JobStatus.done), "cancelled while rendering"),
        (lambda s, j: s.fail(j, None, "over the time limit"), "cancelled (over the time limit)"),
        (lambda s, j: s.requeue(j, 7) == JobStatus.cancelled, "cancelled (its try was given back)"),
        (lambda s, j: s.worker_died(7, 2, "render worker killed") == [(j, "cancelled")], "cancelled (render worker"),
    ],
    ids=["finished-its-last-band", "failed", "given-back", "worker-died"],
)
def test_store_an_accepted_cancel_wins_over_the_try_s_end(tmp_path, end, error):
    """The cancel race: a cancel accepted while the job ran (202) and a try that ends before it looks again
    (its last band done, a time limit, a shutdown, a crash). However the try ends, the job ends cancelled."""
    store = JobStore(tmp_path)
    job_id = add(store)
    store.claim(pid=7)
    assert store.cancel(job_id)["status"] == "running"  # a running job is asked to stop, not ended
    assert end(store, job_id)
    row = store.get(job_id)
    assert row["status"] == "cancelled"
    assert row["error"].startswith(error)
    assert row["finished_at"] is not None
    assert json.loads(row["tries"])[-1]["outcome"] in ("cancelled", "lost")
    assert store.cancel(job_id)["status"] == "cancelled" and not store.finish(job_id, 7, JobStatus.done)


def test_store_names_a_job_s_files(tmp_path):
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


def test_store_one_server_per_data_directory(tmp_path):
    from server.main import lock_data_dir

    lock = lock_data_dir(tmp_path)
    with pytest.raises(RuntimeError, match="another server"):
        lock_data_dir(tmp_path)
    lock.close()
    lock_data_dir(tmp_path).close()


def test_store_jobs_have_owners_and_an_older_table_gains_the_column(tmp_path):
    """A job's owner is its token's hash; a database from before owners gets the column, its rows unowned
    (the instructor's: server/core/security.py), and lists filter by owner."""
    import sqlite3

    store = JobStore(tmp_path)
    old = add(store)
    store.db.execute("DROP INDEX jobs_owner")
    store.db.execute("ALTER TABLE jobs DROP COLUMN owner")  # as a data directory made before owners
    store.db.close()
    assert "owner" not in {r[1] for r in sqlite3.connect(tmp_path / "jobs.sqlite3").execute("PRAGMA table_info(jobs)")}
    store = JobStore(tmp_path)
    assert store.get(old)["owner"] is None
    mine = store.create(json.dumps({"camera": {}}), name=None, width=4, height=4, spp=1, priority=0, warnings=[],
                        max_seconds=60, max_queued=100, owner="a" * 64)["id"]  # fmt: skip
    assert store.get(mine)["owner"] == "a" * 64
    assert [r["id"] for r in store.list_jobs(owner="a" * 64)[0]] == [mine]
    assert store.list_jobs(owner="b" * 64) == ([], 0)
    assert {r["id"] for r in store.list_jobs()[0]} == {old, mine}


def test_store_peek_reads_a_row_without_its_scene_and_never_waits_for_a_lock(tmp_path):
    """`peek` is read in the API's event loop (GET /api/jobs/{id}): the row without its scene; where the
    database is locked it raises at once instead of waiting (the route then reads in a thread), and `wait`
    reads it once the lock is gone."""
    import sqlite3
    import time

    store = JobStore(tmp_path)
    job_id = add(store)
    row = store.peek(job_id)
    assert row["id"] == job_id
    assert "scene" not in row
    assert row["status"] == JobStatus.queued
    assert store.peek("j" * len(job_id)) is None

    for local in (store._local, store._quick):  # this thread's connections closed: the locker's is the only one
        local.conn.close()
        del local.conn
    locker = sqlite3.connect(store.db_path, isolation_level=None)
    locker.execute("PRAGMA locking_mode=EXCLUSIVE")  # a writer that keeps the whole file to itself
    locker.execute("BEGIN EXCLUSIVE")
    locker.execute("UPDATE jobs SET priority = 5 WHERE id = ?", (job_id,))
    locker.execute("COMMIT")  # still held: exclusive locking mode keeps the lock after the commit
    started = time.monotonic()
    with pytest.raises(sqlite3.OperationalError):
        store.peek(job_id)
    assert time.monotonic() - started < 1.0  # at once, not after the store's 30 s busy timeout
    got = []
    reader = threading.Thread(target=lambda: got.append(store.peek(job_id, wait=True)))
    reader.start()
    locker.close()  # the lock goes with the connection
    reader.join(timeout=30)
    assert got
    assert got[0]["priority"] == 5
    assert "scene" not in got[0]


def test_store_rows_are_typed_with_every_column_of_the_table(tmp_path):
    """`JobRowWithScene` (what `get` and every `SELECT *` return) names each column of the jobs table and no
    other, `JobRow` each but the scene (what `peek` and the watcher's `rows` return): the type checker then
    knows the keys that the service, the queues and `JobPublic.from_row` read."""
    store = JobStore(tmp_path)
    columns = {r["name"] for r in store.db.execute("PRAGMA table_info(jobs)")}
    assert set(JobRowWithScene.__required_keys__) == columns
    assert set(JobRow.__required_keys__) == columns - {"scene"}
    job_id = add(store)
    assert set(store.get(job_id)) == columns
    assert set(store.peek(job_id)) == columns - {"scene"}
    assert set(store.rows([job_id])[job_id]) == columns - {"scene"}
