"""Benchmark of the job queue across worker hosts (docs/scale.md): the Redis backend with 1 and 2
worker hosts against the embedded backend.

    python -m bench.cluster [--jobs 60] [--size 256x192] [--spp 36] [--threads 1]

Everything runs on this machine: a redis-server on a loopback port, the API (`python -m server
--redis URL --workers 0`) and the worker hosts (`python -m server.worker --redis URL --threads T`),
each a process of its own, as they would be on separate machines (but sharing this machine's cores:
say how many there are when you quote the numbers). It measures:

1. a batch of `--jobs` small renders (Whitted's scene, distinct seeds) with 1 and with 2 worker hosts:
   the wall time from the first submit to the last job done, and the efficiency T1 / (k Tk);
2. the cost of the queue per job: jobs submitted one at a time to idle workers, the time from
   submit to done less the render's own time (the try's start to end on its host), and the time
   from submit to start, for the Redis backend and for the embedded one (`--workers 1`);
3. bytes per job through Redis: the server's network counters (in and out) over the batch.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.service import Api, free_port

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"


class Procs:
    """The processes of one run, stopped together (by pid) at the end."""

    def __init__(self, root: Path):
        self.root, self.procs = root, []

    def start(self, name: str, argv: list[str], env: dict | None = None) -> subprocess.Popen:
        log = open(self.root / f"{name}.log", "wb")  # noqa: SIM115 (closed with the process)
        p = subprocess.Popen(argv, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        self.procs.append((p, log))
        return p

    def stop(self) -> None:
        for p, _ in reversed(self.procs):
            if p.poll() is None:
                os.killpg(p.pid, 15)
        for p, log in self.procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, 9)
                p.wait(timeout=10)
            log.close()
        self.procs.clear()


def wait(condition, timeout: float, what: str, interval: float = 0.05):
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out waiting for {what}")
        time.sleep(interval)


def scene(args, seed: int) -> dict:
    data = json.loads((SCENES / "whitted.json").read_text())
    w, h = (int(v) for v in args.size.split("x"))
    data["film"].update(width=w, height=h)
    data["sampler"] = {"type": "jittered", "spp": args.spp}
    data.setdefault("render", {})["seed"] = seed
    return data


def start_api(procs: Procs, data_dir: Path, extra: list[str], env: dict) -> Api:
    port = free_port()
    argv = [sys.executable, "-m", "server", "--port", str(port), "--data-dir", str(data_dir), *extra]
    procs.start("api", argv, env)
    api = Api(port)

    def up() -> bool:
        try:
            return bool(api.json("GET", "/api/health"))
        except (OSError, RuntimeError, http.client.HTTPException):
            return False

    wait(up, 180, "the API")
    return api


def run_batch(api: Api, args, seeds: range) -> tuple[float, list[dict]]:
    start = time.monotonic()
    ids = [api.json("POST", "/api/jobs", {"scene": scene(args, s)})["id"] for s in seeds]
    jobs = []
    for job_id in ids:
        jobs.append(wait(lambda j=job_id: (x := api.json("GET", f"/api/jobs/{j}"))["finished"] and x, 3600, "a job"))
    wall = time.monotonic() - start
    bad = [j for j in jobs if j["status"] != "done"]
    if bad:
        raise RuntimeError(f"{len(bad)} job(s) did not finish: {bad[0]['error']}")
    return wall, jobs


def one_at_a_time(api: Api, args, n: int, seed0: int) -> dict:
    """Jobs submitted one after another to idle workers: submit -> start, and the queue's share of
    submit -> done (less the try's own render time on its host)."""
    to_start, overhead, render = [], [], []
    for k in range(n):
        t0 = time.time()
        job = api.json("POST", "/api/jobs", {"scene": scene(args, seed0 + k)})
        done = wait(lambda j=job["id"]: (x := api.json("GET", f"/api/jobs/{j}"))["finished"] and x, 600, "a job", 0.005)
        t1 = time.time()
        last = done["tries"][-1]
        seconds = last["ended_at"] - last["started_at"]
        render.append(seconds)
        overhead.append((t1 - t0) - seconds)
        to_start.append(last["started_at"] - t0)
    return {
        "render_s": round(statistics.median(render), 4),
        "overhead_s": round(statistics.median(overhead), 4),
        "overhead_share": round(statistics.median(overhead) / statistics.median(render), 4),
        "submit_to_start_s": round(statistics.median(to_start), 4),
    }


def redis_bytes(url_port: int) -> int:
    out = subprocess.run(
        ["redis-cli", "-p", str(url_port), "info", "stats"], capture_output=True, text=True, check=True
    ).stdout
    stats = dict(line.split(":", 1) for line in out.splitlines() if ":" in line)
    return int(stats["total_net_input_bytes"]) + int(stats["total_net_output_bytes"])


def start_redis(procs: Procs) -> tuple[int, str]:
    """A throwaway redis-server on a free loopback port, no persistence: (its port, its URL)."""
    port = free_port()
    redis_server = shutil.which("redis-server") or "/usr/bin/redis-server"
    procs.start("redis", [redis_server, "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"])
    wait(
        lambda: subprocess.run(["redis-cli", "-p", str(port), "ping"], capture_output=True).returncode == 0,
        30,
        "redis",
    )
    return port, f"redis://127.0.0.1:{port}/0"


def redis_run(args, hosts: int, root: Path) -> dict:
    procs = Procs(root)
    try:
        port, url = start_redis(procs)
        env = {**os.environ, "TRACER_MAX_QUEUED_JOBS": "10000"}
        api = start_api(procs, root / "data", ["--workers", "0", "--redis", url], env)
        for k in range(hosts):
            argv = [sys.executable, "-m", "server.worker", "--redis", url, "--threads", str(args.threads)]
            procs.start(f"host{k}", [*argv, "--name", f"bench-host-{k}"], env)
        wait(lambda: len(api.json("GET", "/api/health")["workers"]) == hosts, 180, f"{hosts} worker host(s)")
        run_batch(api, args, range(10_000, 10_000 + hosts))  # warm: each host has rendered once
        before = redis_bytes(port)
        wall, jobs = run_batch(api, args, range(args.jobs))
        moved = redis_bytes(port) - before
        queue = api.json("GET", "/api/health")["queue"]
        out = {"hosts": hosts, "wall_s": round(wall, 3), "bytes_per_job": moved // args.jobs,
               "file_bytes_per_job": queue.get("bytes", 0) // (args.jobs + hosts)}  # fmt: skip
        if hosts == 1:
            out["single"] = one_at_a_time(api, args, 10, 20_000)
        return out
    finally:
        procs.stop()


def embedded_run(args, root: Path) -> dict:
    procs = Procs(root)
    try:
        env = {**os.environ, "TRACER_RENDER_THREADS": str(args.threads), "TRACER_MAX_QUEUED_JOBS": "10000"}
        api = start_api(procs, root / "data", ["--workers", "1"], env)
        wait(lambda: all(w["ready"] for w in api.json("GET", "/api/health")["workers"]), 180, "the worker")
        run_batch(api, args, range(10_000, 10_001))
        wall, _ = run_batch(api, args, range(args.jobs))
        return {"wall_s": round(wall, 3), "single": one_at_a_time(api, args, 10, 20_000)}
    finally:
        procs.stop()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--jobs", type=int, default=60)
    p.add_argument("--size", default="256x192")
    p.add_argument("--spp", type=int, default=36)
    p.add_argument("--threads", type=int, default=1, help="render threads per worker host")
    p.add_argument("--out", help="write the results as JSON here")
    args = p.parse_args()
    results = {"machine": {"cores": os.cpu_count(), "python": platform.python_version()}, "args": vars(args)}
    with tempfile.TemporaryDirectory(prefix="bench-cluster-") as tmp:
        for name, run in (
            ("embedded", lambda r: embedded_run(args, r)),
            ("redis_1", lambda r: redis_run(args, 1, r)),
            ("redis_2", lambda r: redis_run(args, 2, r)),
        ):
            root = Path(tmp) / name
            root.mkdir()
            results[name] = run(root)
            print(name, json.dumps(results[name]), flush=True)
    t1, t2 = results["redis_1"]["wall_s"], results["redis_2"]["wall_s"]
    results["efficiency_2"] = round(t1 / (2 * t2), 3)
    e, r = results["embedded"]["single"], results["redis_1"]["single"]
    print(
        f"\n{args.jobs} renders of {args.size} at {args.spp} spp, {args.threads} thread(s) per host, "
        f"{os.cpu_count()} cores here\n"
        f"  embedded (1 worker):  {results['embedded']['wall_s']:7.2f} s\n"
        f"  Redis, 1 worker host: {t1:7.2f} s\n"
        f"  Redis, 2 worker hosts:{t2:7.2f} s   efficiency T1/(2 T2) = {results['efficiency_2']:.3f}\n"
        f"  per job, one at a time to idle workers (median): render {r['render_s']:.3f} s;\n"
        f"    queue overhead: Redis {r['overhead_s'] * 1000:.0f} ms ({100 * r['overhead_share']:.1f}% of the render), "
        f"embedded {e['overhead_s'] * 1000:.0f} ms ({100 * e['overhead_share']:.1f}%)\n"
        f"    submit to start: Redis {r['submit_to_start_s'] * 1000:.0f} ms, "
        f"embedded {e['submit_to_start_s'] * 1000:.0f} ms\n"
        f"  through Redis per job: {results['redis_1']['bytes_per_job']} bytes (of which files "
        f"{results['redis_1']['file_bytes_per_job']})"
    )
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
