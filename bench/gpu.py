"""The checks that need a GPU, in one go (docs/scale.md, "GPU worker hosts"). Nothing here runs in the tests.

    python -m bench.gpu [--device cuda:0] [--repeat 3] [--no-host] [--out REPORT.json] [--logs DIR]

1. Renders: Cornell path 256x256 at 64 spp and Whitted 512x512 at 16 spp, the same scene and seed on
   the device and on the CPU (every core), each timed as the best of --repeat after a warm-up render
   (kernels compiled before). Compared: the means (they should agree to ~1e-5) and the pixels. On the
   device: the whole image is one launch per pass, two renders give the same image bit for bit, and
   so does the same render launched in 4096-pixel bands; grading's per-pixel z test finds the device's
   image the same as the CPU's (their differences are below its float floor). Then small renders of the adaptive sampler
   and the radiosity integrator (its solve on the device too), and a ray tree, against the CPU's.
2. A GPU worker host: redis-server, the API (`python -m server --redis URL --workers 0`) and
   `python -m server.worker --redis URL --device cuda:0` on loopback. /api/health shows the host's
   device; two jobs (the Cornell box of part 1, then another seed: the second shows the host warm)
   record the device in the job and in its try, and the image is part 1's device image bit for bit.

Prints a line per check and the whole report as JSON (also to --out); exit status 0 when every check
passed, 1 when one failed, 2 when there is no such device. A part whose programs or packages are
missing is reported as skipped: part 1 needs the project's renderer (warp-lang, numpy, pydantic,
trimesh, Pillow); part 2 also redis-server, the service's packages (fastapi, uvicorn, redis, rq,
pydantic-settings, ...) and OpenEXR. The processes' logs go to --logs (default: a temporary folder).
"""

from __future__ import annotations

import argparse
import http.client
import importlib.util
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

from bench.service import Api, free_port

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"
MEAN_TOLERANCE = 1e-4  # relative difference of the means, CPU against GPU (measured ~1e-5 on an H200)
GRADING_ALPHA = 1e-3  # grading's default: the share of pixels a correct image may have rejected by chance
SMOKE_TOLERANCE = 1e-3  # the same for the small adaptive and radiosity renders (few pixels; a solve's hits)


def scene_data(name: str, width: int, height: int, sampler: dict | None = None, seed: int | None = None) -> dict:
    data = json.loads((SCENES / f"{name}.json").read_text())
    data.setdefault("film", {}).update(width=width, height=height)
    if sampler is not None:
        data["sampler"] = sampler
    if seed is not None:
        data.setdefault("render", {})["seed"] = seed
    return data


class Report:
    def __init__(self) -> None:
        self.data: dict = {"checks": [], "parts": {}}

    def check(self, name: str, ok: bool, **facts) -> bool:
        self.data["checks"].append({"check": name, "ok": bool(ok), **facts})
        detail = ", ".join(f"{k}={v}" for k, v in facts.items())
        print(f"{'PASS' if ok else 'FAIL'} {name}" + (f": {detail}" if detail else ""), flush=True)
        return ok

    def ok(self) -> bool:
        return all(c["ok"] for c in self.data["checks"])


def compare(a, b) -> dict:
    """How two images of the same scene and seed differ: their means, and the pixels."""
    import numpy as np

    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    d = np.abs(a64 - b64)
    ma, mb = float(a64.mean()), float(b64.mean())
    return {
        "mean_gpu": round(ma, 7),
        "mean_cpu": round(mb, 7),
        "rel_mean_diff": float(f"{abs(ma - mb) / max(abs(mb), 1e-12):.3g}"),
        "mean_abs_diff": float(f"{d.mean():.3g}"),
        "max_abs_diff": float(f"{d.max():.3g}"),
        "pixels_off_1e-3": round(float((d.max(axis=-1) > 1e-3).mean()), 5),
    }


def timed(cs, device: str, repeat: int, **kw):
    """A warm-up render, then the best of `repeat`: (result, seconds)."""
    from tracer.rendering.progressive import render

    render(cs, device=device, **kw)
    best, result = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        result = render(cs, device=device, **kw)
        best = min(best, time.perf_counter() - t)
    return result, best


def part_renders(args, report: Report) -> dict:
    import numpy as np

    from tracer.grading.metrics import pixel_test
    from tracer.kernels.compile import compile_scene
    from tracer.kernels.parallel import default_threads, is_cuda
    from tracer.rendering.progressive import Renderer, load_kernels, render
    from tracer.rendering.raytree import ray_tree
    from tracer.scene import load_scene

    dev = args.device
    t = time.perf_counter()
    load_kernels(dev)
    compile_gpu = time.perf_counter() - t
    t = time.perf_counter()
    load_kernels("cpu")
    compile_cpu = time.perf_counter() - t
    out: dict = {"kernels_s": {dev: round(compile_gpu, 2), "cpu": round(compile_cpu, 2)}, "cases": {}}
    print(f"kernels ready: {dev} {compile_gpu:.1f} s, cpu {compile_cpu:.1f} s", flush=True)
    images = {}
    for name, data in (
        ("cornell_path_256_64spp", scene_data("cornell_path", 256, 256, {"type": "jittered", "spp": 64})),
        ("whitted_512_16spp", scene_data("whitted", 512, 512, {"type": "jittered", "spp": 16})),
    ):
        scene, _ = load_scene(data)
        gpu_cs, cpu_cs = compile_scene(scene, device=dev), compile_scene(scene)
        r = Renderer(gpu_cs, device=dev)
        if is_cuda(dev):  # (--device cpu is a dry run of this script: bands there)
            whole = (r.band, r.threads) == (scene.film.width * scene.film.height, 1)
            report.check(f"{name}: one launch per pass on {dev}", whole, band=r.band, threads=r.threads)
        gpu, gpu_s = timed(gpu_cs, dev, args.repeat)
        cpu, cpu_s = timed(cpu_cs, "cpu", args.repeat)
        facts = compare(gpu.image, cpu.image)
        out["cases"][name] = {
            "gpu_s": round(gpu_s, 4),
            "cpu_s": round(cpu_s, 4),
            "cpu_threads": default_threads(),
            "speedup": round(cpu_s / gpu_s, 1),
            "gpu_mrays_s": round(gpu.rays["total"] / gpu_s / 1e6, 1),
            "rays": [gpu.rays["total"], cpu.rays["total"]],
            **facts,
        }
        print(f"{name}: {dev} {gpu_s:.4f} s, cpu {cpu_s:.4f} s ({default_threads()} threads)", flush=True)
        report.check(f"{name}: means agree", facts["rel_mean_diff"] < MEAN_TOLERANCE, **facts)
        spp = scene.sampler.spp
        share, zmax, _ = pixel_test(gpu.image, cpu.image, cpu.aovs["variance"], spp, spp, gpu.aovs["variance"])
        zfacts = {"rejected": share, "max_z": round(float(zmax.max()), 3)}
        report.check(f"{name}: grading's z test sees the CPU's image (same seed)", share <= GRADING_ALPHA, **zfacts)
        again = render(gpu_cs, device=dev)
        report.check(f"{name}: the same image twice on {dev}", np.array_equal(again.image, gpu.image))
        banded = render(gpu_cs, device=dev, band=4096)
        report.check(f"{name}: whole image = 4096-pixel bands on {dev}", np.array_equal(banded.image, gpu.image))
        images[name] = (data, gpu.image, cpu.image)
    for name, data in (
        ("adaptive_128", scene_data("antialias_adaptive", 128, 96)),
        ("radiosity_96", scene_data("cornell_radiosity", 96, 96, {"type": "jittered", "spp": 4})),
    ):
        scene, _ = load_scene(data)
        t = time.perf_counter()
        gpu = render(compile_scene(scene, device=dev), device=dev)
        gpu_s = time.perf_counter() - t
        cpu = render(compile_scene(scene))
        facts = compare(gpu.image, cpu.image)
        if gpu.solve:
            facts["shots"] = (gpu.solve["shots"], cpu.solve["shots"])
        out["cases"][name] = {"gpu_s": round(gpu_s, 3), **facts}
        report.check(f"{name}: means agree", facts["rel_mean_diff"] < SMOKE_TOLERANCE, **facts)
    scene, _ = load_scene(scene_data("whitted", 64, 48, {"type": "jittered", "spp": 4}))
    trees = [ray_tree(compile_scene(scene, device=d), 44, 28, 1, device=d) for d in (dev, "cpu")]
    same = len(trees[0]["nodes"]) == len(trees[1]["nodes"])
    diff = float(np.abs(np.subtract(trees[0]["color"], trees[1]["color"])).max())
    report.check("ray tree: the same nodes and colour", same and diff < 1e-4, nodes=len(trees[0]["nodes"]), diff=diff)
    out["_images"] = images
    return out


def part_host(args, report: Report, images: dict, logs: Path) -> dict:
    import numpy as np
    import redis

    from bench.cluster import Procs, wait
    from tracer.rendering.film import read_exr

    server = shutil.which("redis-server") or "/usr/bin/redis-server"
    procs = Procs(logs)
    out: dict = {}
    try:
        port = free_port()
        procs.start("redis", [server, "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"])
        url = f"redis://127.0.0.1:{port}/0"
        wait(lambda: _ping(redis, url), 30, "redis-server")
        api_port = free_port()
        api_argv = [sys.executable, "-m", "server", "--port", str(api_port), "--data-dir", str(logs / "data")]
        procs.start("api", [*api_argv, "--workers", "0", "--redis", url])
        api = Api(api_port, timeout=120)
        wait(lambda: _up(api), 300, "the API")
        t = time.perf_counter()
        host = [sys.executable, "-m", "server.worker", "--redis", url, "--device", args.device, "--name", "gpu-host"]
        procs.start("host", host)

        def described() -> list:
            workers = api.json("GET", "/api/health")["workers"]
            return workers if workers and workers[0].get("device") else []

        (worker,) = wait(described, 300, "the GPU worker host")
        out["host_start_s"] = round(time.perf_counter() - t, 2)
        ok = worker["device"] == args.device
        report.check("/api/health shows the host's device", ok, device=worker["device"], threads=worker["threads"])
        data, gpu_image, cpu_image = images["cornell_path_256_64spp"]
        for k, body in enumerate((data, {**data, "render": {**data.get("render", {}), "seed": 11}}), start=1):
            t = time.perf_counter()
            job = api.json("POST", "/api/jobs", {"scene": body})
            done = wait(lambda j=job["id"]: (x := api.json("GET", f"/api/jobs/{j}"))["finished"] and x, 300, "a job")
            tries = done["tries"]
            last = tries[-1] if tries else {}
            facts = {
                "submit_to_done_s": round(time.perf_counter() - t, 3),
                "try_s": round(last["ended_at"] - last["started_at"], 3) if last.get("ended_at") else None,
                "status": done["status"],
                "error": done["error"],
                "devices": [done["device"], *(x["device"] for x in tries)],
            }
            out[f"job{k}"] = facts
            ok = done["status"] == "done" and facts["devices"] == [args.device, args.device]
            report.check(f"job {k} done on {args.device}, the device in its record and its try", ok, **facts)
            if k == 1 and done["status"] == "done":
                _, exr = api.call("GET", f"/api/jobs/{done['id']}/image?format=exr")
                (logs / "job1.exr").write_bytes(exr)
                image = read_exr(logs / "job1.exr")
                report.check("job 1: part 1's device image, bit for bit", np.array_equal(image, gpu_image))
                facts = compare(image, cpu_image)
                ok = facts["rel_mean_diff"] < MEAN_TOLERANCE
                report.check("job 1: against the CPU's image, the means agree", ok, **facts)
    finally:
        procs.stop()
    return out


def _ping(redis, url: str) -> bool:
    try:
        return bool(redis.Redis.from_url(url, socket_timeout=2).ping())
    except redis.RedisError:
        return False


def _up(api: Api) -> bool:
    try:
        return api.call("GET", "/api/health")[0] == 200
    except (OSError, http.client.HTTPException):
        return False


def missing(modules: list[str], programs: list[str] = ()) -> list[str]:
    gone = [m for m in modules if importlib.util.find_spec(m) is None]
    return gone + [p for p in programs if not (shutil.which(p) or Path(f"/usr/bin/{p}").exists())]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--device", default="cuda:0", help="the GPU to check (default cuda:0)")
    p.add_argument("--repeat", type=int, default=3, help="timed renders per case (the best counts)")
    p.add_argument("--no-host", action="store_true", help="only part 1 (no redis-server, API or worker host)")
    p.add_argument("--out", help="write the report as JSON here")
    p.add_argument("--logs", help="folder for the processes' logs and the job's image (default: a temporary one)")
    args = p.parse_args()
    report = Report()
    report.data["machine"] = {"cores": os.cpu_count(), "python": platform.python_version(), "device": args.device}
    gone = missing(["warp", "numpy", "pydantic", "trimesh", "PIL"])
    if gone:
        print(f"cannot render: missing {', '.join(gone)}", file=sys.stderr)
        return 2
    from tracer.kernels.parallel import DeviceError, check_device

    try:
        args.device = check_device(args.device)
    except DeviceError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import warp as wp

    d = wp.get_device(args.device)
    report.data["machine"].update(name=d.name, warp=wp.config.version)
    print(f"{args.device}: {d.name}; warp {wp.config.version}; {os.cpu_count()} CPU cores", flush=True)
    renders = part_renders(args, report)
    images = renders.pop("_images")
    report.data["parts"]["renders"] = renders
    gone = missing(["fastapi", "uvicorn", "redis", "rq", "pydantic_settings", "OpenEXR"], ["redis-server"])
    if args.no_host:
        report.data["parts"]["host"] = "skipped: --no-host"
    elif gone:
        report.data["parts"]["host"] = f"skipped: missing {', '.join(gone)}"
        print(report.data["parts"]["host"], flush=True)
    else:
        logs = Path(args.logs or tempfile.mkdtemp(prefix="bench-gpu-"))
        logs.mkdir(parents=True, exist_ok=True)
        print(f"worker host: logs in {logs}", flush=True)
        try:
            report.data["parts"]["host"] = part_host(args, report, images, logs)
        except Exception as exc:  # a report with what went wrong beats a traceback without the rest
            report.check("worker host", False, error=f"{type(exc).__name__}: {exc}")
    report.data["ok"] = report.ok()
    text = json.dumps(report.data, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0 if report.ok() else 1


if __name__ == "__main__":
    sys.exit(main())
