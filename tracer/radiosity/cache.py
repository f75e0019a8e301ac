"""Radiosity solutions kept on disk (.npz), by the content of what they solve."""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from tracer.kernels.compile import CompiledScene
from tracer.radiosity.patches import Patches
from tracer.radiosity.solver import Solution

PACKAGE = Path(__file__).parent  # its code is part of every solution's key


class SolutionCache:
    """Radiosity solutions on disk, by the content of what they solve: a second render or ray tree of the
    same scene (whatever its camera's view, film or sampler) reads the solution in milliseconds
    instead of solving it again. At most `keep` solutions; the least recently used go first."""

    def __init__(self, folder: Path | str, keep: int = 64):
        self.folder, self.keep = Path(folder), keep

    @staticmethod
    def key(cs: CompiledScene) -> str:
        """A hash of everything the solve depends on: the flattened shapes, triangles, materials (their
        textures' pixels too), lights, the solve's settings and seed, the camera's position (planes are
        clipped to a box that holds it), and the code of this package (tracer/radiosity/)."""
        h = hashlib.sha256()
        d = cs.data
        for arr in (d.shapes, d.materials, d.lights, d.mesh_points, d.mesh_indices, d.face_obj, d.face_mat):
            h.update(arr.numpy().tobytes())
        h.update(d.tex_pixels.numpy().tobytes())
        sc = cs.scene
        meta = {
            "radiosity": sc.render.radiosity.model_dump(mode="json"),
            "seed": sc.render.seed,
            "camera": [sc.camera.lookfrom, sc.camera.lookat],
            "objects": [o.type for o in sc.objects],
            "names": cs.material_names,
        }
        h.update(json.dumps(meta, sort_keys=True).encode())
        for module in sorted(PACKAGE.glob("*.py")):
            h.update(module.read_bytes())
        return h.hexdigest()[:32]

    def has(self, key: str) -> bool:
        """Is a solution of this key kept?"""
        return (self.folder / f"{key}.npz").is_file()

    def get(self, key: str) -> Solution | None:
        path = self.folder / f"{key}.npz"
        try:
            with np.load(path, allow_pickle=False) as z:
                sol = _solution_from(dict(z))
        except (OSError, ValueError, KeyError):
            return None
        path.touch()  # recently used
        return sol

    def put(self, key: str, sol: Solution) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = self.folder / f".{key}.{os.getpid()}.npz"
        arrays: dict[str, Any] = _solution_arrays(sol)  # Any: no key is taken for savez's options
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, self.folder / f"{key}.npz")
        files = sorted(self.folder.glob("*.npz"), key=lambda p: p.stat().st_mtime)
        for old in files[: max(0, len(files) - self.keep)]:
            old.unlink(missing_ok=True)


PATCH_FIELDS = [f.name for f in fields(Patches)]


def _solution_arrays(sol: Solution) -> dict[str, np.ndarray]:
    out = {f"patches.{name}": np.asarray(getattr(sol.patches, name)) for name in PATCH_FIELDS}
    for name in ("radiosity", "unshot", "emitted", "absorbed", "escaped", "direct"):
        out[name] = np.asarray(getattr(sol, name))
    out["corners"], out["corners_ind"] = np.asarray(sol.corners), np.asarray(sol.corners_ind)
    steps = sorted(sol.snapshots)
    out["snapshot_steps"] = np.asarray(steps, dtype=np.int64)
    out["snapshots"] = np.stack([sol.snapshots[k] for k in steps]) if steps else np.zeros((0, len(sol.patches), 3))
    scalars = {"threshold": sol.threshold, "max_steps": sol.max_steps, "rays": sol.rays, "seconds": sol.seconds}
    out["meta"] = np.asarray(json.dumps({"history": sol.history, **scalars}))
    return out


def _solution_from(z: dict) -> Solution:
    patches = Patches(**{name: z[f"patches.{name}"] for name in PATCH_FIELDS})
    meta = json.loads(str(z["meta"]))
    sol = Solution(patches, z["radiosity"], z["unshot"], z["emitted"], z["absorbed"], z["escaped"], meta["history"])
    sol.direct = z["direct"]
    sol.snapshots = {int(k): v for k, v in zip(z["snapshot_steps"], z["snapshots"], strict=True)}
    sol.threshold, sol.max_steps, sol.rays, sol.seconds = (
        meta["threshold"],
        meta["max_steps"],
        meta["rays"],
        meta["seconds"],
    )
    sol.reported, sol.cached = 1.0, True
    sol.corners, sol.corners_ind = z["corners"], z["corners_ind"]
    return sol
