"""The same Cornell box in Mitsuba 3 (PyPI `mitsuba`), for `python -m tracer bench --mitsuba`.

Our scene (quads, boxes, diffuse materials, one quad light, the `path` integrator) is written out as
OBJ meshes and a Mitsuba scene dictionary: two-sided diffuse BSDFs with the same reflectances, an
area emitter of the same radiance, the same camera, and Mitsuba's `path` integrator with
max_depth = ours + 1 (Mitsuba counts path segments, we count bounces; docs/scene-format.md).
The llvm_ad_rgb variant needs Debian's libllvm19: DRJIT_LIBLLVM_PATH is pointed at it when present.
"""

from __future__ import annotations

import glob
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from tracer.compile import box_faces
from tracer.scene import Scene


def available() -> list[str]:
    """The Mitsuba variants that can run here (scalar_rgb; llvm_ad_rgb with libLLVM)."""
    try:
        import mitsuba  # noqa: F401
    except ImportError:
        return []
    out = ["scalar_rgb"]
    if os.environ.get("DRJIT_LIBLLVM_PATH") or glob.glob("/usr/lib/*/libLLVM-1[5-9]*.so*"):
        out.append("llvm_ad_rgb")
    return out


def _llvm_path() -> None:
    if not os.environ.get("DRJIT_LIBLLVM_PATH"):
        found = sorted(glob.glob("/usr/lib/*/libLLVM-19*.so*") or glob.glob("/usr/lib/*/libLLVM-1[5-8]*.so*"))
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found[0]


def _quad_obj(path: Path, quads: list) -> None:
    lines, k = [], 1
    for c, e1, e2 in quads:
        c, e1, e2 = (np.asarray(v, float) for v in (c, e1, e2))
        for v in (c, c + e1, c + e1 + e2, c + e2):
            lines.append(f"v {v[0]:.9g} {v[1]:.9g} {v[2]:.9g}")
        lines.append(f"f {k} {k + 1} {k + 2}\nf {k} {k + 2} {k + 3}")
        k += 4
    path.write_text("\n".join(lines) + "\n")


def scene_dict(scene: Scene, spp: int, folder: Path) -> dict:
    """A Mitsuba scene dict equivalent to `scene` (quads, boxes, quad lights, diffuse kd only)."""
    c = scene.camera
    d: dict = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": scene.render.max_depth + 1},
        "sensor": {
            "type": "perspective",
            "fov": c.vfov,
            "fov_axis": "y",
            "to_world": __import__("mitsuba")
            .ScalarTransform4f()
            .look_at(origin=list(c.lookfrom), target=list(c.lookat), up=list(c.vup)),
            "film": {
                "type": "hdrfilm",
                "width": scene.film.width,
                "height": scene.film.height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "stratified", "sample_count": spp},
        },
    }
    for i, obj in enumerate(scene.objects):
        mat = scene.materials[obj.material] if isinstance(obj.material, str) else obj.material
        if obj.type == "quad":
            quads = [(obj.corner, obj.edge1, obj.edge2)]
        elif obj.type == "box":
            quads = box_faces(obj.min, obj.max, obj.transform)
        else:
            raise ValueError(f"objects[{i}]: only quads and boxes are converted, not {obj.type}")
        f = folder / f"obj{i}.obj"
        _quad_obj(f, quads)
        d[f"obj{i}"] = {
            "type": "obj",
            "filename": str(f),
            "face_normals": True,
            "bsdf": {
                "type": "twosided",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(mat.kd)}},
            },
        }
    for k, light in enumerate(scene.lights):
        if light.type != "quad":
            raise ValueError(f"lights[{k}]: only quad lights are converted")
        f = folder / f"light{k}.obj"
        _quad_obj(f, [(light.corner, light.edge1, light.edge2)])
        d[f"light{k}"] = {
            "type": "obj",
            "filename": str(f),
            "face_normals": True,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": list(light.radiance)}},
        }
    return d


def render(scene: Scene, spp: int, variant: str, seed: int = 0) -> tuple[np.ndarray, float]:
    """(linear RGB image, seconds of the timed render); a small render first warms up (JIT, threads)."""
    if variant.startswith("llvm"):
        _llvm_path()
    import mitsuba as mi

    mi.set_variant(variant)
    with tempfile.TemporaryDirectory() as tmp:
        sc = mi.load_dict(scene_dict(scene, spp, Path(tmp)))
        np.asarray(mi.render(sc, spp=spp, seed=seed + 1))  # warm-up: the same size so JIT kernels are reused
        t0 = time.perf_counter()
        img = np.asarray(mi.render(sc, spp=spp, seed=seed))
        seconds = time.perf_counter() - t0
    return img[..., :3].astype(np.float32), seconds
