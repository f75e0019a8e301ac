"""`python -m server` on a data directory it cannot use (issue #15, item 7): a damaged job database (random
bytes, a truncated file), an empty or missing database beside job folders, a read-only data directory (a
read-only tmpfs mount: the test runs as root, who ignores mode bits), a data directory that is a file, and
one another server holds. Each time: one message on stderr that says what is wrong and what to do, a
non-zero exit status, no traceback, and every file of the data directory as it was (server/core/startup.py)."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from server.core.startup import StartupError
from server.jobs.store import JobStore
from tests.support.api import Server, free_port
from tests.support.disk import tmpfs
from tests.support.scene import ROOT


def start(data_dir: Path, timeout: float = 120) -> tuple[int, str]:
    """`python -m server` on `data_dir`: its exit status and its output, once it has exited by itself."""
    cmd = [sys.executable, "-m", "server", "--port", str(free_port()), "--data-dir", str(data_dir), "--workers", "0"]
    env = {**os.environ, "TRACER_INTERACTIVE_WORKERS": "0"}
    try:
        done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as e:  # it served instead of refusing (killed by subprocess.run)
        raise AssertionError(f"the server did not refuse to start: {e.stderr}") from None
    return done.returncode, done.stdout + done.stderr


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under `folder` by relative path, with its content's hash."""
    if folder.is_file():
        return {folder.name: hashlib.sha256(folder.read_bytes()).hexdigest()}
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder"
        for p in sorted(folder.rglob("*"))
    }


def with_jobs(data_dir: Path, n: int = 3, scene_bytes: int = 100) -> list[str]:
    """A data directory with `n` queued jobs, each with a file in its folder; their ids."""
    store = JobStore(data_dir)
    ids = []
    for i in range(n):
        row = store.create(
            json.dumps({"name": "x" * scene_bytes, "i": i}), name=None, width=4, height=4, spp=1, priority=0,
            warnings=[], max_seconds=60, max_queued=10_000,
        )  # fmt: skip
        store.save_file(row["id"], "image.png", b"\x89PNG picture")
        ids.append(row["id"])
    store.db.execute("PRAGMA wal_checkpoint(TRUNCATE)")  # everything in jobs.sqlite3 itself
    store.db.close()
    return ids


def refused(data_dir: Path, *words: str) -> str:
    """Start on `data_dir`; assert it refused with a message holding `words`, changing nothing."""
    before = snapshot(data_dir)
    code, out = start(data_dir)
    assert code != 0, out
    assert "Traceback" not in out and "cannot start: " in out, out
    message = out[out.index("cannot start: ") :]
    for w in words:
        assert w in message, message
    assert snapshot(data_dir) == before  # nothing changed, nothing removed
    return message


def test_startup_random_bytes_for_a_database(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "jobs.sqlite3").write_bytes(os.urandom(8192))
    refused(data, "jobs.sqlite3 is damaged (file is not a database)", "Restore it from a backup", "move the data")


def test_startup_a_truncated_database(tmp_path):
    data = tmp_path / "data"
    with_jobs(data, n=300, scene_bytes=3000)  # about 1 MB of rows: cut in half, its pages point past the end
    db = data / "jobs.sqlite3"
    os.truncate(db, db.stat().st_size // 2)
    refused(data, "jobs.sqlite3 is damaged (", "Restore it from a backup", "Nothing was changed")


def test_startup_an_empty_database_beside_job_folders_is_refused(tmp_path):
    """A 0-byte jobs.sqlite3 used to start silently as a new database, and the janitor then removed every
    job folder as an orphan."""
    data = tmp_path / "data"
    ids = with_jobs(data)
    (data / "jobs.sqlite3").write_bytes(b"")
    message = refused(data, "jobs.sqlite3 is an empty file", "3 job folder(s)", "Restore jobs.sqlite3 from a backup")
    assert all((data / "jobs" / i / "image.png").is_file() for i in ids), message


def test_startup_a_missing_database_beside_job_folders_is_refused(tmp_path):
    data = tmp_path / "data"
    with_jobs(data, n=2)
    (data / "jobs.sqlite3").unlink()
    refused(data, "jobs.sqlite3 is missing", "2 job folder(s)")


def test_startup_an_empty_database_without_job_folders_is_a_new_one(tmp_path):
    """The same empty file on a fresh data directory is no loss: the server starts on it."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "jobs.sqlite3").write_bytes(b"")
    with Server(data, workers=0) as server:
        assert server.client.get("/api/jobs").json()["count"] == 0


def test_startup_a_data_directory_that_is_a_file(tmp_path):
    data = tmp_path / "data"
    data.write_text("not a folder")
    refused(data, "is a file, not a folder")


def test_startup_a_read_only_data_directory(tmp_path):
    """A read-only mount (root ignores chmod, so a read-only tmpfs is the real test): refused before the
    database is opened, with the mount named as the thing to fix."""
    with tmpfs(tmp_path / "mnt") as mnt:
        data = mnt / "data"
        with_jobs(data)
        subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        refused(data, "is not writable (Read-only file system)", "remount it read-write")


def test_startup_a_data_directory_another_server_holds(tmp_path):
    data = tmp_path / "data"
    with Server(data, workers=0):
        code, out = start(data)
        assert code != 0 and "Traceback" not in out, out
        assert "cannot start: another server is using the data directory" in out, out


def test_startup_the_app_checks_too(tmp_path):
    """The app started another way (a TestClient, another ASGI server) runs the same checks in its lifespan."""
    from fastapi.testclient import TestClient

    from server.core.settings import Settings
    from server.main import create_app

    data = tmp_path / "data"
    data.mkdir()
    (data / "jobs.sqlite3").write_bytes(os.urandom(4096))
    with pytest.raises(StartupError, match="is damaged"), TestClient(create_app(Settings(data_dir=data, workers=0))):
        pass


def test_startup_raises_its_soft_open_files_limit_for_its_connections(tmp_path):
    """Started as systemd starts a service (a soft limit of 1 024 open files under a high hard one), the server
    raises its own soft limit to TRACER_MAX_CONNECTIONS and its own files (1 000 students following their
    submissions got 500s at 1 024: bench/burst.py); and says so. A hard limit below that is kept, with a
    warning: it takes fewer connections at once (503 past them), rather than fail requests it took."""
    import resource

    import httpx

    from server.core.startup import FILES_PER_CONNECTION, OWN_FILES
    from tests.support.api import wait_for

    def soft_limit(pid: int) -> int:
        line = next(x for x in Path(f"/proc/{pid}/limits").read_text().splitlines() if x.startswith("Max open files"))
        return int(line.split()[3])

    need = 2000 * FILES_PER_CONNECTION + OWN_FILES  # the default TRACER_MAX_CONNECTIONS and the server's own
    hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
    if hard != resource.RLIM_INFINITY and hard < need:
        pytest.fail(f"this test needs a hard open-files limit of {need} or more; this machine's is {hard}")
    short = "open files limited to 1500 (the hard limit): room for 494 connections at once, not TRACER_MAX_CONNECTIONS"
    for limits, want, says in (((1024, hard), need, f"soft limit raised from 1024 to {need}"),
                               ((1024, 1500), 1500, short)):  # fmt: skip
        port = free_port()
        cmd = [sys.executable, "-m", "server", "--port", str(port), "--data-dir", str(tmp_path / f"d{port}"),
               "--workers", "0"]  # fmt: skip
        env = {**os.environ, "TRACER_INTERACTIVE_WORKERS": "0", "TRACER_PREVIEWS_AHEAD": "0"}
        log = tmp_path / f"server-{port}.log"

        def answers(port=port) -> bool:
            try:
                return httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=5).status_code == 200
            except httpx.TransportError:
                return False

        with open(log, "wb") as out:
            as_systemd = lambda lim=limits: resource.setrlimit(resource.RLIMIT_NOFILE, lim)  # noqa: E731
            proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT, preexec_fn=as_systemd)
        try:
            wait_for(answers, 120, "the server to answer", interval=0.2)
            assert soft_limit(proc.pid) == want
            assert says in log.read_text()
        finally:
            proc.terminate()
            proc.wait(timeout=60)
