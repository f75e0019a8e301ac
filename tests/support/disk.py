"""A full disk for the tests: a tmpfs of a given size mounted on a folder, filled; a 507 answer told apart
(tests/server/core/test_disk_full.py and the course's)."""

from __future__ import annotations

import errno
import os
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest

DISK = "48m"  # the tmpfs: room for the database, a few images and the uploads


@contextmanager
def tmpfs(folder: Path, size: str = DISK):
    """A tmpfs mounted on `folder` for the block (the tests run as root); unmounted after. A mount that
    cannot be made fails the test with the reason: it is never skipped."""
    folder.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], capture_output=True)
    if done.returncode != 0:
        pytest.fail(f"cannot mount a tmpfs on {folder} (the test needs root): {done.stderr.decode().strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def fill_up(path: Path) -> None:
    """Append to `path` until its disk has no free byte (ENOSPC)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    try:
        for size in (1 << 20, 4096, 1):
            while True:
                try:
                    os.write(fd, bytes(size))
                except OSError as e:
                    if e.errno != errno.ENOSPC:
                        raise
                    break
    finally:
        os.close(fd)


@contextmanager
def filled(disk: Path):
    """Every free byte of `disk` taken by one file (written until ENOSPC), removed when the block ends."""
    path = disk / "fill"
    fill_up(path)
    try:
        yield path
    finally:
        path.unlink()


def is_507(r) -> None:
    assert r.status_code == 507, r.text
    [error] = r.json()["errors"]
    assert error["message"].startswith("the server's disk is full: nothing of this request was kept"), error
