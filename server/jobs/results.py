"""Finished renders answered again: a render job whose pixels a done job already made is done at once.

Rendering is deterministic (the same scene and seed give the same image bit for bit), so a job
whose result key matches a done render's gets that render's files (hard links: no bytes copied) in a folder
of its own and a row of its own, `done` from the start: it is a job like any other for its client (status,
event stream, image, AOVs, share link), owned by the token that submitted it, and another token gets the
404 of an unknown job. The lessons' panels (web/js/lessons.js) come back this way when a student opens a
lesson again, or opens one rendered ahead at start-up (server/jobs/lesson_panels.py).

The key is everything that changes pixels: the scene (its JSON, canonical: keys sorted; the seed and every
setting are in it), the renderer (the text of every file of tracer/, and Warp's version) and the asset
files a scene may name (their names, sizes and times). Only renders made on the CPU answer (a GPU's floats
differ in the last bits). What is kept is bounded by the jobs themselves: a result lives as long as a done
job has it, and the janitor removes finished jobs past TRACER_KEEP_FINISHED or TRACER_MAX_DATA_BYTES (a hard link
is counted in full for each job: the cap errs on the safe side); no other store grows.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
from pathlib import Path

from tracer.assets import ASSET_DIR

log = logging.getLogger(__name__)

TRACER = Path(__file__).resolve().parents[2] / "tracer"  # the renderer's sources
DEVICE = "cpu"  # the device whose renders answer again


def renderer_version(sources: Path = TRACER, assets: Path = ASSET_DIR) -> str:
    """A digest of what, besides the scene, decides a render's pixels: the renderer's files, Warp's version
    and the asset files (read once at start-up: a changed renderer is a restarted server)."""
    import warp

    digest = hashlib.sha256(f"warp {warp.config.version}\n".encode())
    for path in sorted(sources.rglob("*.py")):
        digest.update(f"{path.relative_to(sources)}\n".encode())
        digest.update(path.read_bytes())
    for path in sorted(p for p in assets.rglob("*") if p.is_file()) if assets.is_dir() else []:
        st = path.stat()
        digest.update(f"{path.relative_to(assets)} {st.st_size} {st.st_mtime_ns}\n".encode())
    return digest.hexdigest()


def result_key(scene_text: str, version: str) -> str:
    """The key of a render's result: the canonical scene (keys sorted, no spaces) and the renderer's version."""
    canonical = json.dumps(json.loads(scene_text), sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(f"{version}\n{canonical}".encode()).hexdigest()


def link_files(source: Path, target: Path, skip: tuple[str, ...] = ()) -> bool:
    """Hard-link (or copy, across file systems) every file of the folder `source` into `target`, but `skip`;
    False when `source` has gone meanwhile (the janitor removed its job)."""
    try:
        names = [p.name for p in source.iterdir() if p.is_file() and p.name not in skip]
    except FileNotFoundError:
        return False
    target.mkdir(parents=True, exist_ok=True)
    try:
        for name in names:
            try:
                os.link(source / name, target / name)
            except OSError as exc:
                if isinstance(exc, FileNotFoundError):
                    raise
                shutil.copyfile(source / name, target / name)
    except FileNotFoundError:
        shutil.rmtree(target, ignore_errors=True)
        return False
    return True
