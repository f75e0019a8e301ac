"""The example scenes' previews: small renders made ahead by the render workers, never in the API process.

At start-up (TRACER_PREVIEWS_AHEAD, on by default) every example whose preview is not on disk is queued as a
job of kind `preview` in the batch lane, owned by no one (the instructor's: students never see these jobs;
the pictures are public through GET /api/scenes/{name}/preview.png). A worker renders them while no student
waits (a batch render gives way to interactive work at its next pass). A finished preview is copied to
DATA/previews/<name>-<key>.png, where <key> is a hash of the preview's scene: an example that changes gets a
new preview, and the old one is never served for it. With TRACER_PREVIEWS_AHEAD off, a preview is queued the
first time its picture is asked for.

Each preview's job id is kept beside it (<name>-<key>.job), so that a restarted server follows the job it
queued before rather than queueing another.
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import threading
from pathlib import Path

from server.core.files import write_atomic
from server.core.settings import Settings
from server.jobs.files import JobFile
from server.jobs.lifecycle import JobKind, JobStatus, Lane
from server.jobs.rows import JobRow
from server.jobs.service import JobService
from server.jobs.store import QueueFull

log = logging.getLogger(__name__)

PRIORITY = -10  # behind anything a person asked for in the same lane


def preview_scene(src: Path, size: int) -> dict:
    """The example at preview size: its longer side `size` pixels."""
    data = json.loads(src.read_text())
    film = data.setdefault("film", {})
    w, h = film.get("width", 256), film.get("height", 256)
    scale = size / max(w, h)
    film.update(width=max(1, round(w * scale)), height=max(1, round(h * scale)))
    return data


class Previews:
    """The previews of the example scenes in `scenes`: their state, and their jobs queued when needed."""

    def __init__(self, settings: Settings, jobs: JobService, scenes: Path):
        self.settings, self.jobs, self.store, self.scenes = settings, jobs, jobs.store, scenes
        self.folder = settings.data_dir / "previews"
        self._lock = threading.Lock()  # one caller queues a scene's job

    def _key(self, name: str) -> tuple[dict, Path]:
        scene = preview_scene(self.scenes / f"{name}.json", self.settings.preview_size)
        text = json.dumps(scene, sort_keys=True)
        key = hashlib.sha256(text.encode()).hexdigest()[:16]
        return scene, self.folder / f"{name}-{key}"

    def file(self, name: str) -> Path | None:
        """The preview's PNG once it is rendered (copied from its finished job), else None."""
        _, base = self._key(name)
        return self._file(base, None)

    def _file(self, base: Path, row: JobRow | None) -> Path | None:
        """The PNG at `base`, copied from the job `row` (read here when None) once it is done."""
        png = base.with_suffix(".png")
        if png.is_file():
            return png
        row = row or self._job(base)
        if row is not None and row["status"] == JobStatus.done:
            image = self.store.job_file(row["id"], JobFile.image_png)
            if image.is_file():
                write_atomic(png, lambda tmp: shutil.copyfile(image, tmp))
                return png
        return None

    def _job(self, base: Path) -> JobRow | None:
        try:
            job_id = json.loads(base.with_suffix(".job").read_text())["job"]
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return self.store.get(job_id) if isinstance(job_id, str) else None

    def state(self, name: str) -> dict:
        """{state: ready | queued | rendering | failed | none, fraction, error}: `none` before it was queued."""
        _, base = self._key(name)
        row = self._job(base)  # read once: the job may end between two reads (then it would read as failed)
        if self._file(base, row) is not None:
            return {"state": "ready", "fraction": 1.0, "error": None}
        if row is None:
            return {"state": "none", "fraction": 0.0, "error": None}
        status = JobStatus(row["status"])
        total = row.get("samples_total") or 0
        fraction = min(1.0, (row.get("samples_done") or 0) / total) if total else 0.0
        if status == JobStatus.queued:
            return {"state": "queued", "fraction": 0.0, "error": None}
        if status == JobStatus.running:
            return {"state": "rendering", "fraction": round(fraction, 3), "error": None}
        if status == JobStatus.done:  # done, yet its picture is gone from the job's folder
            return {"state": "failed", "fraction": 1.0, "error": "the rendered picture is missing"}
        return {"state": "failed", "fraction": fraction, "error": row.get("error") or f"the render {status}"}

    def ensure(self, name: str, retry_failed: bool = False) -> None:
        """Queue the preview's render unless it is on disk or its job is queued, running or done."""
        with self._lock:
            if self.file(name) is not None:
                return
            scene, base = self._key(name)
            row = self._job(base)
            if row is not None and row["status"] != JobStatus.cancelled:
                if row["status"] != JobStatus.failed or not retry_failed:
                    return
            film, spp = scene["film"], (scene.get("sampler") or {}).get("spp", 16)
            try:
                row = self.jobs.submit(
                    json.dumps(scene), name=f"preview of {name}"[:200], width=int(film["width"]),
                    height=int(film["height"]), spp=int(spp) if isinstance(spp, int) else 16, priority=PRIORITY,
                    kind=JobKind.preview, lane=Lane.batch, owner=None,
                )  # fmt: skip
            except QueueFull:
                log.warning("the preview of %s waits: the queue is full", name)
                return
            base.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(base.with_suffix(".job"), lambda tmp: tmp.write_text(json.dumps({"job": row["id"]})))

    def names(self) -> list[str]:
        return sorted(p.stem for p in self.scenes.glob("*.json"))

    def ahead(self) -> None:
        """Queue every missing preview (at start-up: a failed one from before gets another try)."""
        for name in self.names():
            try:
                self.ensure(name, retry_failed=True)
            except Exception:  # one broken example file must not keep the others from rendering
                log.exception("could not queue the preview of %s", name)
