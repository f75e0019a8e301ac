"""Backups (server/core/backup.py, `python -m server backup` and `restore`): a live server on loopback takes
jobs from a thread while `backup` copies its data directory; the copy is restored into a new folder and a
server started on it has every row the manifest counted and every file, its database whole. A restore refuses a
data directory in use, a non-empty one without --force, and a damaged backup."""

from __future__ import annotations

import hashlib
import json
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path

import httpx

from tests.support.api import INSTRUCTOR, Server, bearer, tiny_scene, wait_for
from tests.support.scene import ROOT

SUBMITS = 3000  # jobs the background thread submits at most, until the backup has ended (about 60 s of them)
BEFORE_BACKUP = 4  # jobs submitted (and one rendered) before the backup starts
PACE = 0.02  # seconds between two submissions once the backup has started (an Event's wait: stop ends it at once)


def command(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "server", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)  # fmt: skip


def query(db_path: Path, sql: str) -> list[tuple]:
    db = sqlite3.connect(db_path)
    try:
        return db.execute(sql).fetchall()
    finally:
        db.close()


class Submitter(threading.Thread):
    """Submits tiny jobs as the instructor: BEFORE_BACKUP at once, then, from `go`, one every PACE seconds
    until `stop` is set (SUBMITS at most). Paced, so that jobs still arrive however long the backup takes
    (unpaced, a fast machine could reach the cap before a slow backup's snapshot)."""

    def __init__(self, url: str):
        super().__init__(name="submitter", daemon=True)
        self.url, self.ids, self.errors = url, [], []
        self.go, self.stop = threading.Event(), threading.Event()

    def run(self) -> None:
        with httpx.Client(base_url=self.url, timeout=60, headers=bearer(INSTRUCTOR)) as c:
            for i in range(SUBMITS):
                if i == BEFORE_BACKUP and not self.go.wait(300):
                    self.errors.append("the test never said go")
                    return
                if self.stop.is_set() or (i > BEFORE_BACKUP and self.stop.wait(PACE)):
                    return
                r = c.post("/api/jobs", json={"scene": tiny_scene(seed=i)})
                if r.status_code != 202:
                    self.errors.append(r.text)
                    return
                self.ids.append(r.json()["id"])


def test_backup_of_a_live_server_restored_and_served(tmp_path):
    data, dest, again = tmp_path / "data", tmp_path / "backup-1", tmp_path / "restored"
    env = {"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR, "TRACER_MAX_QUEUED_PER_TOKEN": str(SUBMITS)}  # one token submits
    (data / "lti").mkdir(parents=True)
    (data / "lti" / "private.pem").write_text("an LTI key: backed up with the rest\n")
    with Server(data, workers=1, env=env) as server:
        submitter = Submitter(server.url)
        submitter.start()
        wait_for(lambda: len(submitter.ids) >= BEFORE_BACKUP or submitter.errors, 120, "the first jobs")
        assert submitter.errors == [], submitter.errors
        # one rendered before the backup starts (its image is among the files), whatever the machine's speed
        first = f"/api/jobs/{submitter.ids[0]}"
        wait_for(lambda: server.client.get(first, headers=bearer(INSTRUCTOR)).json()["finished"], 120, "a job rendered")
        submitter.go.set()
        out = command("backup", str(dest), "--data-dir", str(data))
        submitter.stop.set()
        submitter.join(timeout=120)
        assert not submitter.is_alive() and submitter.errors == [], submitter.errors
        assert out.returncode == 0, out.stderr

        refused = command("restore", str(dest), "--data-dir", str(data), "--force")  # the server holds it
        assert refused.returncode == 1
        assert "another server is using the data directory" in refused.stderr

    manifest = json.loads((dest / "manifest.json").read_text())
    summary = json.loads(out.stdout)
    assert summary["files"] == manifest["file_count"] == len(manifest["files"]) > 0
    assert manifest["schema_version"] >= 1
    assert BEFORE_BACKUP <= manifest["rows"]["jobs"] < len(submitter.ids), "jobs came while the backup was taken"
    assert "lti/private.pem" in manifest["files"]
    assert not any(f.startswith(("backups/", "cache/")) or ".tmp" in f for f in manifest["files"])

    (again / "something").mkdir(parents=True)
    refused = command("restore", str(dest), "--data-dir", str(again))
    assert refused.returncode == 1
    assert "is not empty" in refused.stderr
    assert (again / "something").is_dir()
    (again / "something").rmdir()
    out = command("restore", str(dest), "--data-dir", str(again))
    assert out.returncode == 0, out.stderr

    db = again / "jobs.sqlite3"
    assert query(db, "PRAGMA integrity_check") == [("ok",)]
    assert query(db, "PRAGMA user_version") == [(manifest["schema_version"],)]
    for table, n in manifest["rows"].items():
        assert query(db, f'SELECT COUNT(*) FROM "{table}"') == [(n,)], table
    for rel, f in manifest["files"].items():
        assert hashlib.sha256((again / rel).read_bytes()).hexdigest() == f["sha256"], rel
    done = [r[0] for r in query(db, "SELECT id FROM jobs WHERE status = 'done'")]
    assert done, "some jobs had rendered before the backup"
    ids = [r[0] for r in query(db, "SELECT id FROM jobs")]

    with Server(again, workers=0, env=env) as server:
        for jid in ids:
            r = server.client.get(f"/api/jobs/{jid}", headers=bearer(INSTRUCTOR))
            assert r.status_code == 200, r.text
        for jid in done:
            r = server.client.get(f"/api/jobs/{jid}/image", headers=bearer(INSTRUCTOR))
            assert r.status_code == 200 and r.content.startswith(b"\x89PNG"), f"job {jid}'s image"
    assert query(db, "PRAGMA integrity_check") == [("ok",)]


def test_backup_a_damaged_or_unfinished_backup_is_not_restored(tmp_path):
    data = tmp_path / "data"
    (data / "jobs" / "x").mkdir(parents=True)
    db = sqlite3.connect(data / "jobs.sqlite3")
    db.execute("CREATE TABLE jobs (id TEXT)")
    db.execute("INSERT INTO jobs VALUES ('a')")
    db.commit()
    db.close()
    (data / "jobs" / "x" / "image.png").write_bytes(b"pixels")
    out = command("backup", str(tmp_path / "b"), "--data-dir", str(data))
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "b" / "manifest.json").read_text())["rows"] == {"jobs": 1}
    again = command("backup", str(tmp_path / "b"), "--data-dir", str(data))
    assert again.returncode == 1
    assert "is not an empty folder" in again.stderr

    (tmp_path / "b" / "files" / "jobs" / "x" / "image.png").write_bytes(b"pixelz")
    out = command("restore", str(tmp_path / "b"), "--data-dir", str(tmp_path / "r"))
    assert out.returncode == 1 and "files/jobs/x/image.png differs from its checksum" in out.stderr, out.stderr
    assert not (tmp_path / "r" / "jobs.sqlite3").exists()
    (tmp_path / "b" / "manifest.json").unlink()
    out = command("restore", str(tmp_path / "b"), "--data-dir", str(tmp_path / "r"))
    assert out.returncode == 1
    assert "did not finish" in out.stderr
