"""Benchmark: Msamples/s and Mrays/s per ray kind on the example scenes (DESIGN.md, "Speed").

    python -m tracer bench            # every scene in scenes/ at 256x256, plus the targets
    python -m tracer bench --quick    # a smoke run at 64x64

Kernels are compiled (or loaded from Warp's cache) before any timing; each render is timed
whole, from the first band to the last, on `--threads` threads (default one per core).
"""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path

from tracer.compile import compile_scene
from tracer.render import default_threads, render
from tracer.scene import load_scene

SCENES = Path(__file__).resolve().parent.parent / "scenes"
KINDS = ("eye", "shadow", "reflection", "transmission")


def _scene(path: Path, width: int, height: int, **render_opts):
    data = json.loads(path.read_text())
    data.setdefault("film", {}).update(width=width, height=height)
    for section, values in render_opts.items():
        data.setdefault(section, {}).update(values)
    scene, _ = load_scene(data)
    return compile_scene(scene)


def measure(cs, threads: int, repeat: int = 1) -> dict:
    """Best of `repeat` renders: seconds, Msamples/s, Mrays/s in all and per kind."""
    best = None
    for _ in range(repeat):
        r = render(cs, threads=threads)
        if best is None or r.seconds < best.seconds:
            best = r
    samples = cs.data.width * cs.data.height * best.spp
    row = {
        "width": cs.data.width,
        "height": cs.data.height,
        "spp": best.spp,
        "threads": threads,
        "seconds": round(best.seconds, 3),
        "msamples_s": round(samples / best.seconds / 1e6, 3),
        "mrays_s": round(best.rays["total"] / best.seconds / 1e6, 3),
        "rays": best.rays,
    }
    for k in KINDS:
        row[f"mrays_s_{k}"] = round(best.rays[k] / best.seconds / 1e6, 3)
    return row


def main(args) -> int:
    threads = args.threads or default_threads()
    size = 64 if args.quick else 256
    results = {
        "machine": {
            "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(),
        },
        "threads": threads,
        "scenes": {},
        "targets": {},
    }
    # compile before timing anything
    render(_scene(SCENES / "whitted.json", 8, 8, sampler={"spp": 1}), threads=1)
    print(
        f"{'scene':24} {'size':>9} {'spp':>4} {'s':>7} {'Msmp/s':>7} {'Mray/s':>7} "
        + " ".join(f"{k[:6]:>7}" for k in KINDS)
    )
    for path in sorted(SCENES.glob("*.json")):
        row = measure(_scene(path, size, size), threads)
        results["scenes"][path.stem] = row
        print(
            f"{path.stem:24} {size:>4}x{size:<4} {row['spp']:>4} {row['seconds']:>7.2f} {row['msamples_s']:>7.2f} "
            f"{row['mrays_s']:>7.2f} " + " ".join(f"{row['mrays_s_' + k]:>7.2f}" for k in KINDS)
        )
    # the target: Whitted scene 512x512, 16 jittered spp, max_depth 5, and 2 threads vs 1
    tsize = 128 if args.quick else 512
    cs = _scene(SCENES / "whitted.json", tsize, tsize, sampler={"type": "jittered", "spp": 16}, render={"max_depth": 5})
    one = measure(cs, 1)
    many = measure(cs, threads)
    results["targets"] = {
        "whitted_512_16spp": many,
        "whitted_512_16spp_1thread": one,
        "speedup": round(one["seconds"] / many["seconds"], 2),
    }
    print(
        f"\nwhitted {tsize}x{tsize} 16 spp depth 5: {many['seconds']:.2f} s on {threads} threads, "
        f"{one['seconds']:.2f} s on 1 thread, speed-up {results['targets']['speedup']:.2f}x"
    )
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    import argparse

    p = argparse.ArgumentParser()
    p.add_argument("--quick", action="store_true")
    p.add_argument("--threads", type=int)
    p.add_argument("--out")
    main(p.parse_args())
