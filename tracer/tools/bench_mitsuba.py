"""Our path tracer against Mitsuba 3 (PyPI `mitsuba`) on the Cornell box, for `python -m tracer bench --mitsuba`.

Our scene (quads, boxes, diffuse materials, one quad light, the `path` integrator) is written out as
OBJ meshes and a Mitsuba scene dictionary: two-sided diffuse BSDFs with the same reflectances, an
area emitter of the same radiance, the same camera, a box pixel filter, and Mitsuba's `path`
integrator with max_depth = ours + 1 (Mitsuba counts path segments, we count bounces;
docs/scene-format.md). Our `random` sampler is Mitsuba's `independent`, `jittered` its `stratified`.

`compare` times both as whole processes, as a user waits for them (start-up, scene loading, JIT or
kernel loading, the render, the image written): `python -m tracer render` and, for each Mitsuba
variant, tracer/tools/mitsuba_child.py, in turns (ours, llvm_ad_rgb, scalar_rgb, ours, ...), so that the
machine's other load falls on all of them alike; medians of the rounds, wall and CPU time (user +
sys). Mitsuba runs under the interpreter `python` (its own virtual environment, if it is not
installed beside the tracer). Quality: the RMSE of the images against a reference (Mitsuba's
low-discrepancy sampler at 64x the samples; each round with its own seed, the squared errors
averaged), and the samples (and time) our renderer needs to reach the RMSE of Mitsuba's llvm_ad_rgb
variant at the benchmark's samples, from the RMSE after each of our progressive passes; then the
same with the better samplers of both (`better_sampling`). The llvm_ad_rgb variant needs a
libLLVM (Debian's libllvm19; Mitsuba's JIT fails with LLVM 15 on this AVX-512 machine):
DRJIT_LIBLLVM_PATH is pointed at the newest found.
"""

from __future__ import annotations

import glob
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tracer.meshing import box_faces
from tracer.scene import Scene

CHILD = Path(__file__).resolve().parent / "mitsuba_child.py"
SAMPLERS = {"random": "independent", "jittered": "stratified", "lowdiscrepancy": "ldsampler"}  # ours -> Mitsuba's


def available(python: str | None = None) -> list[str]:
    """The Mitsuba variants that can run under `python` (default: this interpreter): scalar_rgb, and
    llvm_ad_rgb where a libLLVM is found."""
    code = "import mitsuba, sys; sys.stdout.write(' '.join(mitsuba.variants()))"
    try:
        out = subprocess.run([python or sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired):
        return []
    if out.returncode != 0:
        return []
    have = out.stdout.split()
    found = [v for v in ("llvm_ad_rgb", "scalar_rgb") if v in have]
    if "llvm_ad_rgb" in found and not (
        os.environ.get("DRJIT_LIBLLVM_PATH") or glob.glob("/usr/lib/*/libLLVM-1[5-9]*.so*")
    ):
        found.remove("llvm_ad_rgb")
    return found


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
    """A Mitsuba scene dict equivalent to `scene` (quads, boxes, quad lights, diffuse kd only), as plain
    JSON: the sensor's transform is given by its look-at parameters (`look_at`), which
    tracer/tools/mitsuba_child.py turns into Mitsuba's transform. The meshes are written into `folder`."""
    c = scene.camera
    if scene.sampler.type not in SAMPLERS:
        raise ValueError(f"sampler.type: only {', '.join(SAMPLERS)} have a Mitsuba sampler, not {scene.sampler.type}")
    d: dict = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": scene.render.max_depth + 1},
        "sensor": {
            "type": "perspective",
            "fov": c.vfov,
            "fov_axis": "y",
            "look_at": {"origin": list(c.lookfrom), "target": list(c.lookat), "up": list(c.vup)},
            "film": {
                "type": "hdrfilm",
                "width": scene.film.width,
                "height": scene.film.height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": SAMPLERS[scene.sampler.type], "sample_count": spp},
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


def write_spec(scene: Scene, spp: int, folder: Path) -> Path:
    """The scene for tracer/tools/mitsuba_child.py: its meshes and SPEC.json in `folder`."""
    path = folder / "mitsuba_scene.json"
    path.write_text(json.dumps(scene_dict(scene, spp, folder)))
    return path


def _timed(cmd: list[str], cwd: str | None = None) -> tuple[subprocess.CompletedProcess, float, float]:
    """Run a whole process: (its result, wall seconds, CPU seconds (user + sys) of it and its children)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({out.returncode}):\n{out.stderr[-2000:]}")
    return out, wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def run_mitsuba(python: str, spec: Path, variant: str, spp: int, out: Path, seed: int = 0, threads: int = 0) -> dict:
    """One Mitsuba render as a whole process: wall and CPU seconds, its own split, and the image."""
    cmd = [python, str(CHILD), str(spec), variant, str(spp), str(out), "--seed", str(seed), "--threads", str(threads)]
    res, wall, cpu = _timed(cmd)
    inner = json.loads(res.stdout.strip().splitlines()[-1])
    return {"wall": wall, "cpu": cpu, "render_s": inner["render_s"], "image": np.load(out)}


def run_ours(
    scene_file: Path, out: Path, threads: int | None = None, tree: str | None = None, seed: int | None = None
) -> dict:
    """One render by our command line as a whole process (`python -m tracer render`): wall and CPU
    seconds, the render's own seconds (its last line), and the image (its EXR). `tree`: the checkout
    whose tracer runs (another commit's, to compare), by default this one."""
    from tracer.rendering.film import read_exr

    cmd = [sys.executable, "-m", "tracer", "render", str(scene_file), "-o", str(out.with_suffix(".png"))]
    cmd += ["--exr", str(out.with_suffix(".exr")), "-q"] + (["--threads", str(threads)] if threads else [])
    cmd += ["--seed", str(seed)] if seed is not None else []
    res, wall, cpu = _timed(cmd, cwd=tree or str(Path(__file__).resolve().parents[2]))
    # "OUT.png: 256x256, 64 spp, 1.23 s, ... rays ...": the render's seconds follow the spp
    seconds = float(res.stdout.strip().splitlines()[-1].split(" spp, ")[1].split(" s,")[0])
    return {"wall": wall, "cpu": cpu, "render_s": seconds, "image": read_exr(out.with_suffix(".exr"))}


def rmse(img: np.ndarray, ref: np.ndarray, mask: np.ndarray | None = None) -> float:
    """The root mean squared error of `img` against `ref`, over the pixels of `mask` (all by default)."""
    sq = ((np.asarray(img, np.float64) - ref) ** 2).mean(axis=-1)
    return float(np.sqrt(sq.mean() if mask is None else sq[mask].mean()))


def interior(ref: np.ndarray, bright: float = 1.5, rim: int = 3) -> np.ndarray:
    """The pixels away from the light: not within `rim` pixels of one whose reference radiance (mean of
    the channels) is above `bright`. The light's edges are where the film position matters most (a
    radiance of 17 next to 0.7), and they weigh most in a whole image's RMSE; inside, the noise is the
    paths' own."""
    near = ref.mean(axis=-1) > bright
    for _ in range(rim):
        grown = near.copy()
        grown[1:] |= near[:-1]
        grown[:-1] |= near[1:]
        grown[:, 1:] |= near[:, :-1]
        grown[:, :-1] |= near[:, 1:]
        near = grown
    return ~near


def spp_to_reach(curve: list[tuple[int, float]], target: float) -> float | None:
    """The samples per pixel at which RMSE falls to `target`, from (spp, RMSE) pairs in increasing spp:
    interpolated on log-log axes between the two passes that bracket it (RMSE ~ spp^-1/2 for Monte
    Carlo, so a straight line there), extrapolated from the last two when none does; None for fewer
    than two points."""
    pts = [(s, e) for s, e in curve if s > 0 and e > 0]
    if len(pts) < 2:
        return None
    k = next((k for k in range(len(pts) - 1) if pts[k][1] >= target >= pts[k + 1][1]), None)
    if k is None:  # not bracketed: the first two passes when the target is above them, else the last two
        k = 0 if target > pts[0][1] else len(pts) - 2
    (s0, e0), (s1, e1) = pts[k], pts[k + 1]
    if e0 == e1:
        return float(s1)
    slope = (math.log(s1) - math.log(s0)) / (math.log(e1) - math.log(e0))
    return float(math.exp(math.log(s0) + slope * (math.log(target) - math.log(e0))))


def summary(rs: list[dict], ref_img: np.ndarray, inside: np.ndarray) -> dict:
    """One renderer's rounds: median wall, CPU and render seconds, and the RMSE against `ref_img` (the root
    of the squared errors averaged over the rounds, each with its own seed), each round's too, and over
    the pixels `inside` (see `interior`)."""
    return {
        "wall": statistics.median(x["wall"] for x in rs),
        "cpu": statistics.median(x["cpu"] for x in rs),
        "render": statistics.median(x["render_s"] for x in rs),
        "walls": [round(x["wall"], 3) for x in rs],
        "rmse": math.sqrt(statistics.fmean(rmse(x["image"], ref_img) ** 2 for x in rs)),
        "rmse_rounds": [round(rmse(x["image"], ref_img), 6) for x in rs],
        "rmse_interior": math.sqrt(statistics.fmean(rmse(x["image"], ref_img, inside) ** 2 for x in rs)),
        "mean": float(rs[0]["image"].mean()),
    }


def compare(
    data: dict,
    python: str,
    variants: list[str],
    rounds: int = 3,
    threads: int | None = None,
    ref_factor: int = 64,
    baseline: str | None = None,
) -> dict:
    """The whole-process comparison of our renderer and Mitsuba's `variants` on the scene `data` (a scene
    dict with its film, sampler and max_depth set), `rounds` turns each, alternating; then the quality:
    RMSE against Mitsuba's render at ref_factor x the samples with its low-discrepancy sampler (`ldsampler`:
    at 16x with the independent one, the reference's own noise, about 0.008 here, hid the differences of the
    better samplers, whose errors are near 0.013) (each round renders with its own seed;
    the RMSE is the root of the mean squared error over the rounds, as one image's RMSE swings with its
    few brightest pixels), and the samples our renderer needs to reach the RMSE of the first variant
    (llvm_ad_rgb when there). `baseline`: another checkout of the
    tracer (the commit before a change), timed in the same turns as "baseline". Prints as it goes;
    returns every number."""
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    scene, _ = load_scene(data)
    spp = scene.sampler.spp
    assert spp is not None, "the Sampler's validator fills in its type's default spp"
    out: dict = {"spp": spp, "size": [scene.film.width, scene.film.height], "max_depth": scene.render.max_depth}
    out["sampler"] = scene.sampler.type
    out["threads"] = threads or os.cpu_count()
    out["load_before"] = os.getloadavg()
    runs: dict[str, list[dict]] = {name: [] for name in ["ours", *(["baseline"] if baseline else []), *variants]}
    with tempfile.TemporaryDirectory(prefix="tracer-bench-") as tmp:
        folder = Path(tmp)
        scene_file = folder / "scene.json"
        scene_file.write_text(json.dumps(data))
        spec = write_spec(scene, spp, folder)
        for r in range(-1, rounds):  # round -1 warms up (Warp's and Dr.Jit's kernel caches), untimed
            if r < 0:
                run_ours(scene_file, folder / "ours", threads)
                if baseline:
                    run_ours(scene_file, folder / "baseline", threads, tree=baseline)
                for v in variants:
                    run_mitsuba(python, spec, v, spp, folder / f"{v}.npy", threads=threads or 0)
                continue
            seed = r + 1  # each round its own seed, the same for every renderer: the RMSE is a mean over rounds
            runs["ours"].append(run_ours(scene_file, folder / "ours", threads, seed=seed))
            if baseline:
                runs["baseline"].append(run_ours(scene_file, folder / "baseline", threads, tree=baseline, seed=seed))
            for v in variants:
                runs[v].append(run_mitsuba(python, spec, v, spp, folder / f"{v}.npy", seed=seed, threads=threads or 0))
            line = ", ".join(f"{k} {x[-1]['wall']:.2f} s" for k, x in runs.items())
            print(f"  round {r + 1}/{rounds}: {line}", flush=True)
        ref_variant = variants[0]
        ref_spp = spp * ref_factor
        ref_data = json.loads(json.dumps(data))
        ref_data["sampler"] = {"type": "lowdiscrepancy", "spp": ref_spp}
        (folder / "reference").mkdir()
        ref_spec = write_spec(load_scene(ref_data)[0], ref_spp, folder / "reference")
        ref = run_mitsuba(python, ref_spec, ref_variant, ref_spp, folder / "ref.npy", seed=12345, threads=threads or 0)
        out["reference"] = f"Mitsuba {ref_variant}, ldsampler, {ref_spp} spp"
        ref_img = ref["image"].astype(np.float64)
        inside = interior(ref_img)
        out["interior_pixels"] = int(inside.sum())
        out["load_after"] = os.getloadavg()
        for name, rs in runs.items():
            out[name] = summary(rs, ref_img, inside)
        # our RMSE after each progressive pass (1, 2, 4, ... spp) up to 4x the samples, in process, the
        # squared errors averaged over the first three rounds' seeds
        more = json.loads(json.dumps(data))
        more["sampler"]["spp"] = spp * 4
        sq: dict[int, list[float]] = {}
        sq_in: dict[int, list[float]] = {}

        def on_pass(p) -> None:
            sq.setdefault(p.spp_done, []).append(rmse(p.image, ref_img) ** 2)
            sq_in.setdefault(p.spp_done, []).append(rmse(p.image, ref_img, inside) ** 2)

        for seed in range(1, min(rounds, 3) + 1):
            more.setdefault("render", {})["seed"] = seed
            render(load_scene(more)[0], threads=threads, on_pass=on_pass)
        curve = [(s, math.sqrt(statistics.fmean(v))) for s, v in sorted(sq.items())]
        curve_in = [(s, math.sqrt(statistics.fmean(v))) for s, v in sorted(sq_in.items())]
        out["ours"]["rmse_curve"] = [[s, round(e, 6)] for s, e in curve]
        out["ours"]["rmse_curve_interior"] = [[s, round(e, 6)] for s, e in curve_in]
        target = out[ref_variant]["rmse"]
        need = spp_to_reach(curve, target)
        need_in = spp_to_reach(curve_in, out[ref_variant]["rmse_interior"])
        o = out["ours"]
        fixed = o["wall"] - o["render"]  # start-up, loading and writing: the same at any spp
        out["equal_quality"] = {
            "target": f"the RMSE of Mitsuba {ref_variant} at {spp} spp",
            "target_rmse": target,
            "ours_spp": need,
            "ours_wall": None if need is None else fixed + o["render"] * need / spp,
            "ours_spp_interior": need_in,
            "ours_wall_interior": None if need_in is None else fixed + o["render"] * need_in / spp,
        }
        if scene.sampler.type == "random":
            out["better_sampling"] = better_sampling(
                data, python, ref_variant, out[ref_variant], ref_img, inside, rounds, threads, folder
            )
    return out


def better_sampling(
    data: dict,
    python: str,
    variant: str,
    theirs: dict,
    ref_img: np.ndarray,
    inside: np.ndarray,
    rounds: int,
    threads: int | None,
    folder: Path,
) -> dict:
    """Equal quality with better sampling than the independent one. Ours: the `lowdiscrepancy` sampler
    (film positions from each pixel's low-discrepancy sequence, as the path's bounces already are): its
    RMSE against `ref_img` at 1/8 to 4x the scene's samples, each count rendered in process (three seeds,
    the squared errors averaged), gives the fewest samples that reach the RMSE of `theirs` (Mitsuba
    `variant`'s summary with its independent sampler at the scene's samples); then our whole process at
    those samples,
    and Mitsuba `variant` with its own better samplers (`stratified`, `ldsampler`) at the scene's
    samples, in alternating rounds. Also the samples (and the time they take, from the whole process's
    fixed cost and render time) we need to reach each of those samplers' RMSE, and each RMSE over the
    `inside` pixels only (`interior`). Returns every number; prints as it goes."""
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    spp = data["sampler"]["spp"]

    def ours(n: int, seed: int | None = None) -> dict:
        d = json.loads(json.dumps(data))
        d["sampler"] = {"type": "lowdiscrepancy", "spp": n}
        if seed is not None:
            d.setdefault("render", {})["seed"] = seed
        return d

    # each count rendered on its own: a first n of a pixel's samples that is no power of two spreads
    # less evenly than the progressive passes' 1, 2, 4, ... would suggest
    counts = sorted({max(1, spp * k // 16) for k in (2, 3, 4, 5, 6, 7, 8, 10, 12, 16, 24, 32, 48, 64)})
    curve, curve_in = [], []
    for n in counts:
        images = [render(load_scene(ours(n, seed))[0], threads=threads).image for seed in (1, 2, 3)]
        curve.append((n, math.sqrt(statistics.fmean(rmse(m, ref_img) ** 2 for m in images))))
        curve_in.append((n, math.sqrt(statistics.fmean(rmse(m, ref_img, inside) ** 2 for m in images))))
    print("  ours lowdiscrepancy, RMSE: " + ", ".join(f"{n} spp {e:.5f}" for n, e in curve), flush=True)
    print("    inside: " + ", ".join(f"{n} spp {e:.5f}" for n, e in curve_in), flush=True)
    target = theirs["rmse"]
    n_spp = next((n for n, e in curve if e <= target), counts[-1])  # the fewest listed that reach it
    out: dict = {"target_rmse": target, "curve": [[n, round(e, 6)] for n, e in curve], "ours_spp": n_spp}
    out["curve_interior"] = [[n, round(e, 6)] for n, e in curve_in]
    scene_file = folder / "lowdiscrepancy.json"
    scene_file.write_text(json.dumps(ours(n_spp)))
    specs = {}
    for ours_type, mitsuba_type in (("jittered", "stratified"), ("lowdiscrepancy", "ldsampler")):
        sub = folder / mitsuba_type
        sub.mkdir(exist_ok=True)
        d = json.loads(json.dumps(data))
        d["sampler"] = {"type": ours_type, "spp": spp}
        specs[mitsuba_type] = write_spec(load_scene(d)[0], spp, sub)
    runs: dict[str, list[dict]] = {"ours": [], **{k: [] for k in specs}}
    for r in range(rounds):
        seed = r + 1
        runs["ours"].append(run_ours(scene_file, folder / "ours_ld", threads, seed=seed))
        for name, spec in specs.items():
            runs[name].append(
                run_mitsuba(python, spec, variant, spp, spec.parent / "m.npy", seed=seed, threads=threads or 0)
            )
        line = ", ".join(f"{k} {x[-1]['wall']:.2f} s" for k, x in runs.items())
        print(f"  round {r + 1}/{rounds}: ours lowdiscrepancy {n_spp} spp and Mitsuba's samplers: {line}", flush=True)
    for name, rs in runs.items():
        out[name] = summary(rs, ref_img, inside)
    o = out["ours"]
    fixed, per_spp = o["wall"] - o["render"], o["render"] / n_spp
    for name, m in [(k, out[k]) for k in specs] + [("independent", theirs)]:
        n = spp_to_reach(curve, m["rmse"])
        n_in = spp_to_reach(curve_in, m["rmse_interior"])
        out.setdefault(name, {})
        out[name]["ours_spp"] = n
        out[name]["ours_wall"] = None if n is None else fixed + per_spp * n
        out[name]["ours_spp_interior"] = n_in
        out[name]["ours_wall_interior"] = None if n_in is None else fixed + per_spp * n_in
    return out


def print_comparison(out: dict) -> None:
    """The table of `compare`'s numbers."""
    w, h = out["size"]
    print(
        f"\nCornell box {w}x{h}, {out['spp']} spp, max_depth {out['max_depth']}, {out['sampler']} sampler, "
        f"{out['threads']} threads; whole processes, medians of {len(out['ours']['walls'])} alternating rounds; "
        f"load average {out['load_before'][0]:.2f} before, {out['load_after'][0]:.2f} after; RMSE against "
        f"{out['reference']}, 'inside' over the {out['interior_pixels']} pixels away from the light (see interior)"
    )
    print(f"  {'renderer':22} {'wall s':>7} {'CPU s':>7} {'render s':>9} {'RMSE':>8} {'inside':>8} {'mean':>7}")
    runs = [k for k in out if isinstance(out[k], dict) and "wall" in out[k]]
    for name in runs:
        r = out[name]
        label = name if name in ("ours", "baseline") else f"Mitsuba {name}"
        print(
            f"  {label:22} {r['wall']:7.2f} {r['cpu']:7.2f} {r['render']:9.2f} {r['rmse']:8.5f} "
            f"{r['rmse_interior']:8.5f} {r['mean']:7.4f}"
        )
    o = out["ours"]
    for name in [k for k in runs if k != "ours"]:
        m = out[name]
        print(f"  ours / {name}: {o['wall'] / m['wall']:.2f}x the wall time, {o['cpu'] / m['cpu']:.2f}x the CPU")
    ref = next(k for k in runs if k not in ("ours", "baseline"))
    q = out["equal_quality"]
    print(f"  equal quality with Mitsuba {ref} at {out['spp']} spp, ours {out['sampler']}: {_reach(q, out[ref])}")
    b = out.get("better_sampling")
    if not b:
        return
    o = b["ours"]
    print(
        f"  ours lowdiscrepancy at {b['ours_spp']} spp: RMSE {o['rmse']:.5f} (inside {o['rmse_interior']:.5f}), "
        f"{o['wall']:.2f} s as a whole process, {o['wall'] / out[ref]['wall']:.2f}x Mitsuba {ref}'s independent "
        f"{out['spp']} spp (RMSE {out[ref]['rmse']:.5f}, inside {out[ref]['rmse_interior']:.5f})"
    )
    reach = _reach(b["independent"], out[ref])
    print(f"  equal quality with Mitsuba {ref} independent {out['spp']} spp, ours lowdiscrepancy: {reach}")
    for name in ("stratified", "ldsampler"):
        m = b[name]
        print(
            f"  Mitsuba {ref} {name} {out['spp']} spp: RMSE {m['rmse']:.5f} (inside {m['rmse_interior']:.5f}), "
            f"{m['wall']:.2f} s; ours lowdiscrepancy to its quality: {_reach(m, m)}"
        )


def _reach(q: dict, theirs: dict) -> str:
    """Our samples and whole-process seconds to reach a quality (whole image, inside), against their time."""
    parts = []
    for key, what in (("", "RMSE"), ("_interior", "inside")):
        n, wall = q.get("ours_spp" + key), q.get("ours_wall" + key)
        if n is None or wall is None:
            parts.append(f"{what}: not reached")
        else:
            parts.append(f"{what}: {n:.1f} spp, {wall:.2f} s ({wall / theirs['wall']:.2f}x)")
    return "; ".join(parts)
