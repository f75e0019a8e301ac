"""Benchmark of similarity reports (tracer/grading/similarity.py, docs/assignments.md): a class of 300 made up
here, its report timed as the service makes it (the students' files on disk, read and compared in one process).

    python -m bench.similarity [--students 300] [--copies 3] [--images] [--json FILE]

The class all start from one starter scene (a floor, a ball, a light) and each makes their own changes: moves
the ball, repaints it, adds two to five things of their own (spheres, boxes, quads, disks) and a light, moves the
camera. `--copies` of them hand in another student's scene with its objects and lights reordered, its
materials renamed and every fractional number nudged by +0.001. The report must flag exactly those pairs, the
copies first. With `--images` the class hands in pictures instead (64 x 48 PNGs of their own shapes), and the
copies another's picture with noise of 1/255 added. Prints a table (or JSON), and what was flagged.
"""

from __future__ import annotations

import argparse
import copy
import io
import json
import random
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tracer.grading import similarity

TARGET_SECONDS = 60.0  # a class of 300, on the 2-core machine of the project (BENCHMARKS.md)


def starter() -> dict:
    """The scene the class is given: a checker floor, a red ball, a point light."""
    return {
        "version": 1,
        "name": "Starter",
        "camera": {"lookfrom": [0, 1.5, 6], "lookat": [0, 0.5, 0], "vup": [0, 1, 0], "vfov": 40},
        "film": {"width": 64, "height": 48},
        "sampler": {"type": "jittered", "spp": 4},
        "materials": {
            "floor": {"kd": 0.8, "texture": {"type": "checker", "size": 1, "color1": 0.85, "color2": 0.25}},
            "red": {"kd": [0.75, 0.15, 0.1], "ks": 0.3, "shininess": 60},
        },
        "lights": [{"type": "point", "position": [2, 5, 3], "intensity": 40}],
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "sphere", "name": "ball", "center": [0, 0.5, 0], "radius": 0.5, "material": "red"},
        ],
    }


def _r(rng: random.Random, lo: float, hi: float) -> float:
    return round(rng.uniform(lo, hi), 2)


def _material(rng: random.Random) -> dict:
    m: dict = {"kd": [_r(rng, 0, 1), _r(rng, 0, 1), _r(rng, 0, 1)]}
    kind = rng.choice(["matte", "shiny", "mirror", "glass"])
    if kind == "shiny":
        m |= {"ks": _r(rng, 0.2, 0.8), "shininess": rng.choice([20, 50, 100, 200])}
    elif kind == "mirror":
        m |= {"kr": _r(rng, 0.5, 1.0)}
    elif kind == "glass":
        m |= {"kd": 0, "kr": _r(rng, 0.05, 0.3), "kt": _r(rng, 0.7, 1.0), "ior": _r(rng, 1.3, 1.9)}
    return m


def _thing(rng: random.Random, material) -> dict:
    x, z = _r(rng, -3, 3), _r(rng, -3, 2)
    kind = rng.choice(["sphere", "box", "quad", "disk"])
    if kind == "sphere":
        r = _r(rng, 0.2, 0.9)
        return {"type": "sphere", "center": [x, r, z], "radius": r, "material": material}
    if kind == "box":
        w, h = _r(rng, 0.3, 1.2), _r(rng, 0.3, 1.5)
        return {"type": "box", "min": [x, 0, z], "max": [round(x + w, 2), h, round(z + w, 2)], "material": material}
    if kind == "quad":
        return {"type": "quad", "corner": [x, 0.01, z], "edge1": [_r(rng, 0.5, 2), 0, 0],
                "edge2": [0, _r(rng, 0.5, 2), 0], "material": material}  # fmt: skip
    return {"type": "disk", "center": [x, _r(rng, 0.5, 2), z], "normal": [0, 0, 1], "radius": _r(rng, 0.2, 1),
            "material": material}  # fmt: skip


def honest(rng: random.Random, base: dict | None = None) -> dict:
    """A student's own scene from the starter: the ball moved and repainted, things and a light of their own,
    the camera moved; materials named and inline as a student would write them."""
    s = copy.deepcopy(base or starter())
    ball = s["objects"][1]
    ball["center"] = [_r(rng, -2, 2), ball["radius"], _r(rng, -2, 1)]
    s["materials"]["red"] = _material(rng)
    for k in range(rng.randint(2, 5)):
        if rng.random() < 0.5:
            name = f"{rng.choice(['my', 'the', 'a'])}_{rng.choice(['gold', 'blue', 'glass', 'metal'])}{k}"
            s["materials"][name] = _material(rng)
            s["objects"].append(_thing(rng, name))
        else:
            s["objects"].append(_thing(rng, _material(rng)))
    s["lights"].append({"type": "point", "position": [_r(rng, -4, 4), _r(rng, 3, 6), _r(rng, -2, 4)],
                        "intensity": _r(rng, 10, 60)})  # fmt: skip
    s["camera"]["lookfrom"] = [_r(rng, -2, 2), _r(rng, 1, 3), _r(rng, 5, 8)]
    return s


def _nudged(v):
    if isinstance(v, float) and v != int(v):
        return round(v + 0.001, 6)
    if isinstance(v, list):
        return [_nudged(x) for x in v]
    if isinstance(v, dict):
        return {k: _nudged(x) for k, x in v.items()}
    return v


def disguised(rng: random.Random, scene: dict) -> dict:
    """Another's scene made to look like one's own: objects and lights reordered, materials renamed (their
    uses with them), every fractional number nudged by +0.001, the scene renamed."""
    s = copy.deepcopy(scene)
    names = {old: f"mat{k}_{rng.randint(100, 999)}" for k, old in enumerate(s["materials"])}
    s["materials"] = {names[k]: v for k, v in s["materials"].items()}
    for o in s["objects"]:
        if isinstance(o["material"], str):
            o["material"] = names[o["material"]]
        o.pop("name", None)
    rng.shuffle(s["objects"])
    rng.shuffle(s["lights"])
    s["name"] = "My own scene"
    for key in ("objects", "lights", "materials", "camera"):
        s[key] = _nudged(s[key])
    return s


def scene_class(n: int, copies: int, seed: int = 1) -> tuple[list[tuple[str, dict]], set[frozenset]]:
    """`n` students' scenes (`copies` of them copied from another) and the copied pairs."""
    rng = random.Random(seed)
    scenes = [(f"s{i:03d}", honest(rng)) for i in range(n - copies)]
    pairs = set()
    for k, (source, scene) in enumerate(rng.sample(scenes, copies)):  # each copy of its own source
        who = f"c{k:03d}"
        scenes.append((who, disguised(rng, scene)))
        pairs.add(frozenset((source, who)))
    return scenes, pairs


def picture(rng: np.random.Generator, size=(48, 64)) -> np.ndarray:
    """A student's render: a sky gradient, a floor and three to six discs of their own, as RGB floats."""
    h, w = size
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.zeros((h, w, 3))
    img[:] = rng.uniform(0.2, 0.8, 3) * (1 - yy[..., None] / h)
    img[yy > h * rng.uniform(0.5, 0.8)] = rng.uniform(0, 1, 3)
    for _ in range(rng.integers(3, 7)):
        cx, cy, r = rng.uniform(0, w), rng.uniform(0, h), rng.uniform(3, 14)
        img[(xx - cx) ** 2 + (yy - cy) ** 2 < r * r] = rng.uniform(0, 1, 3)
    return img


def png(img: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)).save(buf, "PNG")
    return buf.getvalue()


def image_class(n: int, copies: int, seed: int = 1) -> tuple[list[tuple[str, bytes]], set[frozenset]]:
    rng = np.random.default_rng(seed)
    pics = [(f"s{i:03d}", picture(rng)) for i in range(n - copies)]
    pairs = set()
    for k, i in enumerate(rng.choice(len(pics), copies, replace=False)):  # each copy of its own source
        source, img = pics[int(i)]
        pics.append((f"c{k:03d}", img + rng.integers(-1, 2, img.shape) / 255))
        pairs.add(frozenset((source, f"c{k:03d}")))
    return [(who, png(img)) for who, img in pics], pairs


def run(students: int, copies: int, images: bool, folder: Path) -> dict:
    """Write the class's files, make the report from them (timed), and check what it flagged."""
    if images:
        works, copied = image_class(students, copies)
        items = []
        for who, data in works:
            (folder / f"{who}.png").write_bytes(data)
            items.append((who, "png", str(folder / f"{who}.png")))
        starter_json = None
    else:
        scenes, copied = scene_class(students, copies)
        items = []
        for who, scene in scenes:
            (folder / f"{who}.json").write_text(json.dumps(scene))
            items.append((who, "scene", str(folder / f"{who}.json")))
        starter_json = json.dumps(starter())
    t0 = time.perf_counter()
    out = similarity.report_files(items, starter_json)
    seconds = time.perf_counter() - t0
    flagged = [frozenset((p["a"], p["b"])) for p in out["pairs"]]
    group = out["groups"]["image" if images else "scene"]
    return {
        "students": students,
        "kind": "image" if images else "scene",
        "seconds": round(seconds, 3),
        "target_s": TARGET_SECONDS,
        "copied": len(copied),
        "flagged": len(flagged),
        "copies_flagged_first": set(flagged[: len(copied)]) == copied,
        "honest_flagged": len([p for p in flagged if p not in copied]),
        "candidates": group["candidates"],
        "all_pairs": students * (students - 1) // 2,
        "typical": group["typical"],
        "threshold": group["threshold"],
        "skipped": len(out["skipped"]),
    }


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--students", type=int, default=300, help="the class's size (default 300)")
    p.add_argument("--copies", type=int, default=3, help="students who hand in another's work (default 3)")
    p.add_argument("--images", action="store_true", help="pictures (an open-ended task) instead of scenes")
    p.add_argument("--json", metavar="FILE", help="also write the result as JSON")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-similarity-") as tmp:
        result = run(args.students, args.copies, args.images, Path(tmp))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    width = max(len(k) for k in result)
    for k, v in result.items():
        sys.stdout.write(f"{k:<{width}}  {v}\n")
    return result


if __name__ == "__main__":
    main()
