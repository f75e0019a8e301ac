"""The janitor (server/jobs/janitor.py): finished jobs removed by age and by the data directory's size cap,
folders left without a job, and the server running it."""

from __future__ import annotations

from server.jobs.store import JobStore
from tests.support.api import api_client
from tests.support.store import add

DAY = 86400.0
NOW = 1_900_000_000.0  # the present, for the janitor's rounds


def job_in(store: JobStore, status: str, ended: float | None = None, size: int = 1000) -> str:
    """A job in `status` that ended at `ended` (None: still queued/running), with `size` bytes of image."""
    job_id = add(store)
    store.db.execute("UPDATE jobs SET status = ?, finished_at = ? WHERE id = ?", (status, ended, job_id))
    folder = store.job_dir(job_id)
    folder.mkdir()
    (folder / "image.png").write_bytes(b"x" * size)
    return job_id


def janitor(tmp_path, **settings):
    from server.core.settings import Settings
    from server.jobs.janitor import Janitor

    store = JobStore(tmp_path)
    return Janitor(Settings(data_dir=tmp_path, **settings), store), store


def test_janitor_removes_finished_jobs_past_their_time_only(tmp_path):
    jan, store = janitor(tmp_path, keep_finished="7d", max_data_bytes=0)
    old = {s: job_in(store, s, NOW - 8 * DAY) for s in ("done", "failed", "cancelled")}
    recent = job_in(store, "done", NOW - 6 * DAY)
    queued, running = job_in(store, "queued"), job_in(store, "running")
    store.db.execute("UPDATE jobs SET created_at = ? WHERE id IN (?, ?)", (NOW - 30 * DAY, queued, running))
    done = jan.clean(now=NOW)
    assert done.expired == 3
    assert done.for_size == 0
    for job_id in old.values():
        assert store.get(job_id) is None and not (store.job_dir(job_id)).exists()  # row and folder together
    for job_id in (recent, queued, running):  # a queued or running job is never removed, however old
        assert store.get(job_id) is not None and (store.job_dir(job_id) / "image.png").exists()
    assert jan.clean(now=NOW + 2 * DAY).expired == 1  # the recent one, in its turn


def test_janitor_keeps_everything_when_told_to(tmp_path):
    jan, store = janitor(tmp_path, keep_finished=0, max_data_bytes=0)
    job_id = job_in(store, "done", NOW - 1000 * DAY)
    assert jan.clean(now=NOW).expired == 0 and store.get(job_id) is not None


def test_janitor_caps_the_data_directory_oldest_finished_first(tmp_path, caplog):
    from server.jobs.janitor import GRACE, tree_size

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
    with caplog.at_level("WARNING", logger="server.jobs.janitor"):
        assert jan.clean(now=NOW).for_size == 1 and store.get(third) is None
        assert store.get(running) is not None
        assert store.get(just_done) is not None
        jan.clean(now=NOW)
    assert caplog.text.count("no finished job is left to remove") == 1


def test_janitor_sweeps_folders_left_without_a_job(tmp_path):
    import os

    from server.jobs.janitor import GRACE

    jan, store = janitor(tmp_path, keep_finished="7d", max_data_bytes=0)
    kept = job_in(store, "done", NOW)
    orphan = store.jobs_dir / "AAAAAAAAAAAAAAAAAAAAAA"
    orphan.mkdir()
    (orphan / "image.png").write_bytes(b"x")
    fresh = store.jobs_dir / "BBBBBBBBBBBBBBBBBBBBBB"  # a folder being written right now: left alone
    fresh.mkdir()
    other = store.jobs_dir / "not a job"  # not a job id: never touched
    other.mkdir()
    for path in (orphan, store.job_dir(kept)):
        os.utime(path, (NOW - 2 * GRACE, NOW - 2 * GRACE))
    os.utime(fresh, (NOW, NOW))
    assert jan.clean(now=NOW).orphans == 1
    assert not orphan.exists() and fresh.exists() and other.exists() and (store.job_dir(kept)).exists()


def test_janitor_runs_in_the_server(tmp_path):
    """The app's lifespan starts the janitor: a job finished long ago is gone soon after start-up."""
    import time

    store = JobStore(tmp_path)
    old = job_in(store, "done", time.time() - 30 * DAY)
    kept = job_in(store, "done", time.time() - DAY)
    with api_client(tmp_path, keep_finished="7d", janitor_interval=0.05) as client:
        deadline = time.monotonic() + 10
        while client.get(f"/api/jobs/{old}").status_code != 404:
            assert time.monotonic() < deadline, "the janitor did not remove the old job"
            time.sleep(0.05)
        assert client.get(f"/api/jobs/{kept}").status_code == 200
    assert not (tmp_path / "jobs" / old).exists()
