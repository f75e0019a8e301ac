"""Benchmark: Msamples/s and Mrays/s per ray kind on the example scenes (BENCHMARKS.md).

    python -m tracer bench            # every scene in scenes/ at 256x256, plus the targets
    python -m tracer bench --quick    # a smoke run at 64x64
    python -m tracer bench --mitsuba  # also the path-traced Cornell box against Mitsuba 3 (if installed)
    python -m tracer bench --mitsuba --only cornell --mitsuba-python VENV/bin/python --rounds 6

Kernels are compiled (or loaded from Warp's cache) before any timing; each render is timed
whole, from the first band to the last, on `--threads` threads (default one per core).
"""

from __future__ import annotations

import json
import os
import platform
import sys
from pathlib import Path

from tracer.kernels.compile import compile_scene
from tracer.kernels.parallel import default_threads
from tracer.rendering.progressive import render
from tracer.scene import load_scene

SCENES = Path(__file__).resolve().parents[2] / "scenes"
KINDS = ("eye", "shadow", "reflection", "transmission")
SECTIONS = ("scenes", "cornell", "radiosity", "scaling")  # --only picks some of them


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
    assert best is not None, "repeat >= 1 renders"
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
    only = set((getattr(args, "only", None) or ",".join(SECTIONS)).split(","))
    if "scenes" in only:
        scenes(args, threads, size, results)
    if "cornell" in only:
        results["cornell"] = cornell(args, threads)
    if "radiosity" in only:
        results["radiosity"] = radiosity(args)
    if "scaling" in only:
        results["scaling"] = scaling(args, threads)
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=2) + "\n")
    return 0


def scenes(args, threads: int, size: int, results: dict) -> None:
    """Every example scene at size x size with its own spp and depth; the core issue's Whitted target."""
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
    # the core issue's target: Whitted scene 512x512, 16 jittered spp, max_depth 5, and 2 threads vs 1
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


def cornell_data(size: int, spp: int) -> dict:
    """The path-traced Cornell box of issue #17's comparison: scenes/cornell_path.json at size x size, spp
    samples of the random sampler, max_depth 7 (Mitsuba's path integrator with max_depth 8)."""
    data = json.loads((SCENES / "cornell_path.json").read_text())
    data["film"].update(width=size, height=size)
    data["sampler"] = {"type": "random", "spp": spp}
    data["render"]["max_depth"] = 7
    return data


def cornell(args, threads: int) -> dict:
    """The path-traced Cornell box at 256x256 and 512x512, 64 spp (on one thread and on every core); with
    --mitsuba, the whole-process comparison with Mitsuba 3 (tracer/tools/bench_mitsuba.py)."""
    from tracer.tools import bench_mitsuba

    out = {}
    spp = 4 if args.quick else 64
    sizes = (64,) if args.quick else (256, 512)
    print(f"\npath-traced Cornell box (scenes/cornell_path.json, random sampler, max_depth 7), {spp} spp")
    for size in sizes:
        cs = compile_scene(load_scene(cornell_data(size, spp))[0])
        for t in sorted({1, threads}):
            row = measure(cs, t)
            out[f"ours_{size}_{t}t"] = row
            print(f"  ours      {size}x{size}, {t} thread(s): {row['seconds']:7.2f} s  {row['mrays_s']:.2f} Mrays/s")
    if not args.mitsuba:
        return out
    python = args.mitsuba_python or sys.executable
    variants = bench_mitsuba.available(python)
    if not variants:
        print(f"  Mitsuba 3 is not installed for {python} (pip install mitsuba; or --mitsuba-python): no comparison")
        return out
    data = cornell_data(sizes[0], spp)
    for t in [args.threads] if args.threads else sorted({1, default_threads()}):
        baseline = getattr(args, "baseline", None)
        cmp = bench_mitsuba.compare(data, python, variants, rounds=args.rounds, threads=t, baseline=baseline)
        bench_mitsuba.print_comparison(cmp)
        out[f"mitsuba_{t}t"] = cmp
    return out


def radiosity(args) -> dict:
    """The radiosity solver on the Cornell box: patches, form-factor rays per second, seconds to 99%
    of the energy shot, at several patch sizes (how the cost grows with the patch count), on one thread
    and on every core (the shots' rays in bands; the same solution bit for bit)."""
    import time

    from tracer.radiosity import solve

    scene, _ = load_scene(json.loads((SCENES / "cornell_path.json").read_text()))
    cs = compile_scene(scene)
    solve(cs, patch_size=1.0, rays=256, threshold=0.5)  # compile the kernels first
    out = {}
    cores = default_threads()
    print("\nradiosity, Cornell box (scenes/cornell_path.json), 4096 rays per shot, to 99% of the energy shot")
    for size in (0.5,) if args.quick else (0.5, 0.25, 0.125):
        row = {"patch_size": size}
        for threads in sorted({1, cores}):
            t0 = time.perf_counter()
            sol = solve(cs, patch_size=size, rays=4096, threshold=0.01, threads=threads)
            seconds = time.perf_counter() - t0
            row.update(patches=len(sol.patches), shots=len(sol.history), rays=sol.rays)
            row[f"seconds_{threads}t"] = round(seconds, 3)
            row[f"mrays_s_{threads}t"] = round(sol.rays / seconds / 1e6, 3)
        out[str(size)] = row
        times = ", ".join(f"{t} thread(s) {row[f'seconds_{t}t']:6.2f} s" for t in sorted({1, cores}))
        print(
            f"  patch {size:5}: {row['patches']:5} patch sides, {row['shots']:5} shots, {times}, "
            f"{row[f'mrays_s_{cores}t']:.2f} M form-factor rays/s on {cores}"
        )
    return out


def scaling(args, threads: int) -> dict:
    """How the cost grows with pixels, spp, depth and triangle count (Whitted scene; a mesh sphere)."""
    out = {"pixels": {}, "spp": {}, "depth": {}, "triangles": {}}
    q = args.quick
    print("\nscaling (whitted.json unless said)")
    for size in (64, 128) if q else (128, 256, 512):
        out["pixels"][size] = measure(_scene(SCENES / "whitted.json", size, size, sampler={"spp": 4}), threads)
    for spp in (1, 4) if q else (1, 4, 16, 64):
        out["spp"][spp] = measure(_scene(SCENES / "whitted.json", 128, 128, sampler={"spp": spp}), threads)
    for depth in (1, 3) if q else (1, 2, 3, 5, 8):
        out["depth"][depth] = measure(
            _scene(SCENES / "whitted.json", 128, 128, sampler={"spp": 4}, render={"max_depth": depth}), threads
        )
    for sub in (1, 3) if q else (1, 3, 5, 7):
        out["triangles"][sub] = measure(_mesh_scene(sub, 128), threads)
    for key, unit in (("pixels", "px"), ("spp", "spp"), ("depth", "depth"), ("triangles", "subdiv")):
        cells = ", ".join(f"{k} {unit}: {r['seconds']:.2f} s ({r['mrays_s']:.1f} Mrays/s)" for k, r in out[key].items())
        print(f"  {key:9} {cells}")
    for sub, r in out["triangles"].items():
        r["triangle_count"] = 20 * 4**sub
    return out


def _mesh_scene(subdivisions: int, size: int):
    """An icosphere of 20 * 4^subdivisions triangles in front of a light (the triangle-count sweep)."""
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    data = {
        "camera": {"lookfrom": [0, 0, 4], "lookat": [0, 0, 0], "vfov": 40},
        "film": {"width": size, "height": size},
        "sampler": {"type": "jittered", "spp": 4},
        "render": {"max_depth": 2},
        "materials": {"m": {"kd": 0.6, "kr": 0.3}},
        "lights": [{"type": "point", "position": [3, 3, 3], "intensity": 20}],
        "objects": [
            {"type": "mesh", "vertices": ico.vertices.tolist(), "faces": ico.faces.tolist(), "material": "m"},
            {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "m"},
        ],
    }
    scene, _ = load_scene(data)
    return compile_scene(scene)


if __name__ == "__main__":  # pragma: no cover
    import argparse

    p = argparse.ArgumentParser()
    p.add_argument("--quick", action="store_true")
    p.add_argument("--threads", type=int)
    p.add_argument("--out")
    p.add_argument("--mitsuba", action="store_true")
    p.add_argument("--mitsuba-python")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--only")
    p.add_argument("--baseline")
    main(p.parse_args())
