"""The data directory is its user's alone (issue #39, item 12): made 0700, and every file the server, its render
workers and its upkeep commands make in it (the database and its WAL, job images, submissions, backups) 0600.
An earlier release's database (0644) is tightened at the next start."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

from server.core.startup import check_data_dir
from tests.support.api import Server, submit, tiny_scene, wait_finished
from tests.support.scene import ROOT


def modes(root: Path) -> dict[str, int]:
    """Every folder's and file's permission bits under `root` (its own included), by path relative to it."""
    out = {".": stat.S_IMODE(root.stat().st_mode)}
    for here, dirs, files in os.walk(root):
        for name in dirs + files:
            path = Path(here) / name
            out[str(path.relative_to(root))] = stat.S_IMODE(path.lstat().st_mode)
    return out


def test_the_data_directory_is_made_0700_and_an_old_database_tightened(tmp_path):
    umask = os.umask(0o022)
    try:
        data = tmp_path / "new" / "data"
        check_data_dir(data)
        assert stat.S_IMODE(data.stat().st_mode) == 0o700
        old = tmp_path / "old"
        old.mkdir()
        for name in ("jobs.sqlite3", "jobs.sqlite3-wal"):
            (old / name).write_bytes(b"")
            os.chmod(old / name, 0o644)
        check_data_dir(old)
        assert {n: stat.S_IMODE((old / n).stat().st_mode) for n in ("jobs.sqlite3", "jobs.sqlite3-wal")} == {
            "jobs.sqlite3": 0o600,
            "jobs.sqlite3-wal": 0o600,
        }
    finally:
        os.umask(umask)


def test_what_the_server_and_a_backup_make_is_private(tmp_path):
    data = tmp_path / "data"
    data.mkdir(mode=0o700)
    with Server(data, workers=1) as server:
        done = wait_finished(server.client, submit(server.client, tiny_scene())["id"], timeout=120)
        assert done["status"] == "done", done
        dest = tmp_path / "backup"
        taken = subprocess.run([sys.executable, "-m", "server", "backup", str(dest), "--data-dir", str(data)],
                               cwd=ROOT, capture_output=True, text=True, timeout=300)  # fmt: skip
        assert taken.returncode == 0, taken.stderr
        made = modes(data)
    assert "jobs.sqlite3-wal" in made and any(name.endswith(".exr") for name in made), made
    loose = {name: oct(mode) for name, mode in made.items() if mode & 0o077}
    assert not loose, loose
    copied = modes(dest)
    assert copied["."] == 0o700 and "jobs.sqlite3" in copied and len(copied) > 3, copied
    loose = {name: oct(mode) for name, mode in copied.items() if mode & 0o077}
    assert not loose, loose
