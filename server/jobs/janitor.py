"""The janitor: removes finished jobs, rows and folders together, so a long-running server does not
fill its disk.

A round, once at start-up and then every `janitor_interval` seconds, in a thread of the server:
1. every job that finished (done, failed or cancelled) more than `keep_finished` ago is removed;
2. job folders whose row is gone (a removal cut short by a crash) are removed;
3. while the data directory holds more than `max_data_bytes`, the finished job that ended first
   is removed, then the next.
4. the chores others gave it run (the grading runs': a run waiting for space on the disk tries again, since a
   round may have freed some: server/grading/runs.py, `GradeRuns.retry`).
Queued and running jobs are never touched, nor is a job that ended less than `GRACE` seconds ago:
its client (the page, a grading run) may still be fetching its image. Grading runs (grades/) count
towards the size but are an instructor's record: the janitor leaves them alone.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from server.core.ids import looks_like_job_id
from server.core.settings import Settings
from server.jobs.store import JobStore

log = logging.getLogger(__name__)

GRACE = 60.0  # seconds after its end during which a job is never removed


def tree_size(path: Path) -> int:
    """Bytes in the files under `path` (the sum of their sizes); 0 when it does not exist."""
    total, folders = 0, list[str | Path]([path])
    while folders:
        try:
            entries = os.scandir(folders.pop())
        except (FileNotFoundError, NotADirectoryError):
            continue
        with entries:
            for entry in entries:
                try:
                    if entry.is_dir(follow_symlinks=False):
                        folders.append(entry.path)
                    else:
                        total += entry.stat(follow_symlinks=False).st_size
                except FileNotFoundError:  # removed while we looked
                    pass
    return total


@dataclass
class Round:
    """What one round did."""

    expired: int = 0  # jobs removed for their age
    orphans: int = 0  # folders removed because their job's row was gone
    for_size: int = 0  # jobs removed to bring the data directory under its cap
    size: int = 0  # bytes in the data directory after the round


class Janitor:
    def __init__(self, settings: Settings, store: JobStore, chores: tuple[Callable[[], None], ...] = ()):
        self.settings, self.store, self.chores = settings, store, chores
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._warned = False  # over the cap with nothing left to remove: said once, until it changes
        self.measured: tuple[int, float] | None = None  # the data directory's bytes at the last round, and when

    def start(self) -> None:
        self._thread = threading.Thread(target=self._loop, name="janitor", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self.clean()
            except Exception:  # a locked database, a folder we may not remove: try again next round
                log.exception("janitor")
            self._stop.wait(self.settings.janitor_interval)

    def clean(self, now: float | None = None) -> Round:
        """One round (see the module's docstring); `now` is the Unix time it takes as the present."""
        now = time.time() if now is None else now
        store, keep, cap = self.store, self.settings.keep_finished, int(self.settings.max_data_bytes)
        done = Round()
        if keep > 0:
            for job_id in store.finished_before(now - max(keep, GRACE)):
                done.expired += store.remove(job_id)
        known = store.ids()
        for name in store.job_folders():
            if looks_like_job_id(name) and name not in known and self._older(store.job_dir(name), now):
                store.remove_folder(name)
                done.orphans += 1
        done.size = tree_size(store.data_dir)
        if cap > 0 and done.size > cap:
            for job_id in store.finished_before(now - GRACE):
                if done.size <= cap:
                    break
                freed = tree_size(store.job_dir(job_id))
                if store.remove(job_id):
                    done.for_size += 1
                    done.size -= freed
            if done.for_size:
                done.size = tree_size(store.data_dir)  # measured again: the database changed too
        self.measured = (done.size, now)  # what the status page shows (server/core/status.py)
        self._report(done, keep, cap)
        for chore in self.chores:
            try:
                chore()
            except Exception:  # one chore's failure never stops the round's others
                log.exception("janitor: %s", getattr(chore, "__qualname__", chore))
        return done

    @staticmethod
    def _older(folder: Path, now: float) -> bool:
        try:
            return folder.stat().st_mtime < now - GRACE
        except FileNotFoundError:
            return False

    def _report(self, done: Round, keep: float, cap: int) -> None:
        if done.expired:
            log.info("janitor: removed %d job(s) finished more than %s ago", done.expired, _duration(keep))
        if done.orphans:
            log.info("janitor: removed %d job folder(s) left without a job", done.orphans)
        if done.for_size:
            log.info(
                "janitor: removed %d finished job(s), the oldest first, to bring the data directory under %s "
                "(TRACER_MAX_DATA_BYTES); it now holds %s",
                done.for_size, _bytes(cap), _bytes(done.size),
            )  # fmt: skip
        over = cap > 0 and done.size > cap
        if over and not self._warned:
            log.warning(
                "janitor: the data directory holds %s, over its cap of %s, and no finished job is left to remove "
                "(queued and running jobs, jobs that ended in the last minute, and grading runs are kept)",
                _bytes(done.size), _bytes(cap),
            )  # fmt: skip
        self._warned = over


def _duration(seconds: float) -> str:
    for unit, size in (("d", 86400), ("h", 3600), ("m", 60)):
        if seconds >= size and seconds % size == 0:
            return f"{seconds / size:g}{unit}"
    return f"{seconds:g}s"


def _bytes(n: int) -> str:
    for unit, size in (("GB", 10**9), ("MB", 10**6), ("kB", 10**3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n} bytes"
