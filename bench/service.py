"""Benchmark of the rendering service (docs/service.md): first-preview latency and API latency under load.

    python -m bench.service [--runs 5] [--requests 2000] [--workers 1]

It starts `python -m server` on 127.0.0.1 with a fresh data directory, warms it up (kernels loaded,
one job rendered), then measures
1. submit -> first preview of the 256 x 256 example scene `cornell`: the time from sending
   POST /api/jobs to the first `preview` event on the job's event stream, and to having that PNG
   in hand; also by polling GET /api/jobs/{id} every 5 ms;
2. the latency of GET /api/jobs/{id} while long renders keep the worker's threads busy on every
   core: a bounded loop of sequential requests on one keep-alive connection, then the same from
   8 concurrent clients; percentiles, next to the same loop on an idle server;
3. the same GET's latency while 6 clients click pixels of the radiosity Cornell box (POST /api/raytree),
   and while 4 clients validate a scene of 25 000 spheres at once (POST /api/validate), with the
   latency of each click and each validation.

`--validate-only` runs the last measure alone (after the warm-up and one finished job to GET).

`--streams 50,100,200,500` measures open event streams instead (issue #24): for each N, fresh long renders
(one running on each worker, one queued), so that every N meets the same early passes, whose progress events
come at their fastest (later passes have more samples, and their events come slower); N clients each hold
GET /api/jobs/{id}/events open, half on the running render and half on the queued one (read by a process of
their own, so that reading them never holds up the GETs timed here); meanwhile one more client reads
GET /api/jobs/{id} and /api/health in a loop: their p50 and p99, the events the streams received per
second, and the CPU the API process used (seconds of CPU per second: 1.0 is one core). `--redis` runs it on
the Redis backend: a redis-server, the API alone and `--workers` worker hosts (niced, as the embedded workers
are), all here; with `--api-cpus 0` the API runs on core 0 and everything else on the other cores, as if the
worker hosts and the clients were machines of their own.
"""

from __future__ import annotations

import argparse
import http.client
import json
import math
import multiprocessing
import os
import platform
import selectors
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HELPERS: list[subprocess.Popen] = []  # redis-server and worker hosts of a --redis run, stopped at its end
API_CPUS: list[int] = []  # --api-cpus: the cores the API runs on (everything else here runs on the others)
SCENES = ROOT / "scenes"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Api:
    """A keep-alive HTTP/1.1 connection to the server, JSON in and out; with `token`, as its bearer."""

    def __init__(self, port: int, token: str | None = None, timeout: float = 60):
        self.port, self.token, self.timeout = port, token, timeout
        self.conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)

    def call(self, method: str, path: str, body: dict | bytes | None = None) -> tuple[int, bytes]:
        data = body if isinstance(body, bytes) or body is None else json.dumps(body).encode()
        headers = {"content-type": "application/json"} if data is not None else {}
        if self.token is not None:
            headers["Authorization"] = f"Bearer {self.token}"
        try:
            self.conn.request(method, path, body=data, headers=headers)
            r = self.conn.getresponse()
        except (http.client.HTTPException, OSError):
            self.conn.close()  # a dropped keep-alive connection: once more, on a new one
            self.conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=self.timeout)
            self.conn.request(method, path, body=data, headers=headers)
            r = self.conn.getresponse()
        return r.status, r.read()

    def json(self, method: str, path: str, body: dict | None = None) -> dict:
        status, data = self.call(method, path, body)
        if status >= 400:
            raise RuntimeError(f"{method} {path}: {status} {data[:300]!r}")
        return json.loads(data)

    def close(self) -> None:
        self.conn.close()


def start_redis() -> str:
    """A redis-server on a free loopback port, without persistence (one of HELPERS); its URL once it listens."""
    port = free_port()
    argv = ["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"]
    HELPERS.append(subprocess.Popen(argv, stdout=subprocess.DEVNULL))
    for _ in range(100):  # until it listens
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                break
        time.sleep(0.1)
    return f"redis://127.0.0.1:{port}/0"


def stop_helpers() -> None:
    """Stop the worker hosts and the redis-server of a --redis run, the last started first."""
    while HELPERS:
        helper = HELPERS.pop()
        helper.terminate()
        helper.wait(timeout=30)


def start_server(
    data_dir: Path,
    workers: int,
    redis_url: str | None = None,
    *,
    port: int | None = None,
    env: dict | None = None,
    token: str | None = None,
    hosts: bool = True,
) -> tuple[subprocess.Popen, int]:
    """`python -m server` in a process group of its own (a SIGTERM can go to the whole group), its log appended
    to server.log beside `data_dir`; with `redis_url`, the API alone, and (`hosts`) its `workers` worker hosts
    started beside it. `env`: more of the environment; `token`: the one its health is asked with."""
    port = port or free_port()
    cmd = [sys.executable, "-m", "server", "--port", str(port), "--data-dir", str(data_dir)]
    if API_CPUS:  # --api-cpus: the API on cores of its own
        cmd = ["taskset", "-c", ",".join(map(str, API_CPUS))] + cmd
    cmd += ["--workers", "0", "--redis", redis_url] if redis_url else ["--workers", str(workers)]
    log = open(data_dir.parent / "server.log", "ab")  # noqa: SIM115 (lives as long as the server)
    env = {**os.environ, **(env or {})}
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    if redis_url and hosts:
        for k in range(workers):
            # niced as the embedded backend's workers are: here they share the API's cores, not machines of their own
            host = ["nice", "-n", "10", sys.executable, "-m", "server.worker", "--redis", redis_url, "--name", f"b{k}"]
            HELPERS.append(subprocess.Popen(host, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT))
    deadline = time.monotonic() + 180
    while True:
        if proc.poll() is not None:
            raise RuntimeError(f"the server exited; see {data_dir.parent / 'server.log'}")
        try:
            health = Api(port, token).json("GET", "/api/health")
            if len(health["workers"]) >= workers and all(w["ready"] for w in health["workers"]):
                return proc, port
        except (OSError, http.client.HTTPException):
            pass
        if time.monotonic() > deadline:
            raise RuntimeError("the server did not start in time")
        time.sleep(0.2)


def wait_done(api: Api, job_id: str, timeout: float = 300) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        job = api.json("GET", f"/api/jobs/{job_id}")
        if job["status"] in ("done", "failed", "cancelled"):
            return job
        if time.monotonic() > deadline:
            raise RuntimeError(f"job {job_id} did not finish")
        time.sleep(0.05)


def first_preview_by_events(port: int, scene: dict) -> tuple[float, float, str]:
    """Seconds from POST to the first `preview` event, and to that PNG downloaded."""
    api = Api(port)
    t0 = time.perf_counter()
    job = api.json("POST", "/api/jobs", {"scene": scene})
    stream = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    stream.request("GET", job["events_url"])
    r = stream.getresponse()
    event, url = None, None
    while url is None:
        raw = r.readline()
        if not raw:
            raise RuntimeError("event stream closed early")
        line = raw.decode().rstrip("\r\n")
        if line.startswith("event:"):
            event = line.split(":", 1)[1].strip()
        elif line.startswith("data:") and event == "preview":
            url = json.loads(line.split(":", 1)[1])["url"]
        elif line.startswith("data:") and event == "end":
            raise RuntimeError("the job ended without a preview")
    t_event = time.perf_counter() - t0
    status, png = api.call("GET", url)
    t_png = time.perf_counter() - t0
    assert status == 200 and png[:4] == b"\x89PNG"
    stream.close()
    wait_done(api, job["id"])
    api.close()
    return t_event, t_png, job["id"]


def first_preview_by_polling(port: int, scene: dict) -> float:
    api = Api(port)
    t0 = time.perf_counter()
    job = api.json("POST", "/api/jobs", {"scene": scene})
    while api.json("GET", f"/api/jobs/{job['id']}")["preview"] < 1:
        time.sleep(0.005)
    t = time.perf_counter() - t0
    wait_done(api, job["id"])
    api.close()
    return t


def percentiles(ms: list[float]) -> dict:
    ms = sorted(ms)

    def q(p: float) -> float:
        return ms[min(len(ms) - 1, int(round(p / 100 * (len(ms) - 1))))]

    return {"n": len(ms), "p50": q(50), "p90": q(90), "p99": q(99), "max": ms[-1], "mean": statistics.fmean(ms)}


def get_loop(port: int, job_id: str, n: int) -> list[float]:
    api = Api(port)
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        status, _ = api.call("GET", f"/api/jobs/{job_id}")
        out.append((time.perf_counter() - t0) * 1000)
        assert status == 200
    api.close()
    return out


def concurrent_get_loops(port: int, job_id: str, clients: int, n_each: int) -> list[float]:
    results: list[list[float]] = [[] for _ in range(clients)]

    def run(k: int) -> None:
        results[k] = get_loop(port, job_id, n_each)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return [x for r in results for x in r]


def gets_while(port: int, probe: str, work: list) -> list[float]:
    """Run each callable of `work` in a thread of its own, all at once, while one more client reads
    GET /api/jobs/{probe} in a loop: that GET's latencies (ms) until the work is done."""
    done = threading.Event()
    gets: list[float] = []

    def getter() -> None:
        api = Api(port)
        while not done.is_set():
            t = time.perf_counter()
            status, _ = api.call("GET", f"/api/jobs/{probe}")
            gets.append((time.perf_counter() - t) * 1000)
            assert status == 200
        api.close()

    reader = threading.Thread(target=getter)
    reader.start()
    threads = [threading.Thread(target=w) for w in work]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    done.set()
    reader.join()
    return gets


def raytree_load(port: int, probe: str, clients: int = 6, rounds: int = 8) -> dict:
    """`clients` clients click pixels of the radiosity Cornell box (POST /api/raytree), `rounds` clicks each,
    while one client reads GET /api/jobs/{probe} in a loop: that GET's latency, and each click's (the first
    click solves the radiosity; the cache serves the others)."""
    scene = json.loads((SCENES / "cornell_radiosity.json").read_text())
    first = Api(port)
    t0 = time.perf_counter()
    first.json("POST", "/api/raytree", {"scene": scene, "x": 128, "y": 128})
    first_click = time.perf_counter() - t0
    first.close()
    clicks: list[float] = []

    def clicker(k: int) -> None:
        api = Api(port)
        for r in range(rounds):
            t = time.perf_counter()
            api.json("POST", "/api/raytree", {"scene": scene, "x": 20 + 30 * k, "y": 20 + 25 * r})
            clicks.append(time.perf_counter() - t)
        api.close()

    gets = gets_while(port, probe, [lambda k=k: clicker(k) for k in range(clients)])
    return {
        "first_click_s": first_click,
        "click_ms": percentiles([c * 1000 for c in clicks]),
        "get_ms": percentiles(gets),
    }


def spheres_scene(n: int) -> dict:
    """A scene of n small spheres on a grid, one named material: a large scene to validate (25 000 spheres
    are 1.6 MB of compact JSON, under the default TRACER_MAX_BODY_BYTES)."""
    side = math.ceil(math.sqrt(n))
    objects = [
        {"type": "sphere", "center": [k % side - side // 2, 0, k // side - side // 2], "radius": 0.4, "material": "m"}
        for k in range(n)
    ]
    return {
        "camera": {"lookfrom": [0, 60, 120], "lookat": [0, 0, 0]}, "film": {"width": 64, "height": 64},
        "materials": {"m": {"kd": 0.6}}, "lights": [{"type": "point", "position": [0, 80, 0]}], "objects": objects,
    }  # fmt: skip


def validate_load(port: int, probe: str, clients: int = 4, rounds: int = 5, spheres: int = 25_000) -> dict:
    """`clients` clients validate a scene of `spheres` spheres (POST /api/validate), `rounds` times each, all at
    once, while one client reads GET /api/jobs/{probe} in a loop: that GET's latency, and each validation's."""
    body = json.dumps({"scene": spheres_scene(spheres)}, separators=(",", ":")).encode()
    one = Api(port)
    t0 = time.perf_counter()
    status, answer = one.call("POST", "/api/validate", body)
    alone = time.perf_counter() - t0
    assert status == 200 and json.loads(answer)["valid"], answer[:300]
    one.close()
    times: list[float] = []

    def validator() -> None:
        api = Api(port)
        for _ in range(rounds):
            t = time.perf_counter()
            status, answer = api.call("POST", "/api/validate", body)
            times.append(time.perf_counter() - t)
            assert status == 200 and json.loads(answer)["valid"], answer[:300]
        api.close()

    gets = gets_while(port, probe, [validator] * clients)
    return {
        "spheres": spheres, "body_bytes": len(body), "clients": clients, "alone_s": alone,
        "validate_ms": percentiles([v * 1000 for v in times]), "get_ms": percentiles(gets),
    }  # fmt: skip


def cpu_seconds(pid: int) -> float:
    """The CPU time (user + system) a process has used, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Streams:
    """N event streams held open (raw sockets, read and dropped by a process of their own, so that reading
    them never holds up the GETs this process times): GET /api/jobs/{id}/events. `opened`, `bytes` and
    `events` (per kind) are what that process has counted so far."""

    KINDS = ("progress", "preview")

    def __init__(self, port: int, job_ids: list[str], n: int):
        ctx = multiprocessing.get_context("fork")
        self.counts = ctx.Array("q", 2 + len(self.KINDS), lock=False)  # opened, bytes, then each kind's events
        self.stop = ctx.Event()
        self.reader = ctx.Process(target=self._read, args=(port, job_ids, n), daemon=True)
        self.reader.start()

    @property
    def opened(self) -> int:
        return self.counts[0]

    @property
    def bytes(self) -> int:
        return self.counts[1]

    @property
    def events(self) -> dict[str, int]:
        return {kind: self.counts[2 + k] for k, kind in enumerate(self.KINDS)}

    def _read(self, port: int, job_ids: list[str], n: int) -> None:
        selector, counts = selectors.DefaultSelector(), self.counts
        names = [b"event: " + kind.encode() + b"\n" for kind in self.KINDS]
        for k in range(n):
            s = socket.create_connection(("127.0.0.1", port))
            path = f"/api/jobs/{job_ids[k % len(job_ids)]}/events"
            s.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nAccept: text/event-stream\r\n\r\n".encode())
            s.setblocking(False)
            selector.register(s, selectors.EVENT_READ, {"head": b"", "tail": b""})
        while not self.stop.is_set():
            for key, _ in selector.select(timeout=0.2):
                try:
                    data = key.fileobj.recv(65536)
                except BlockingIOError:
                    continue
                if not data:
                    selector.unregister(key.fileobj)
                    continue
                counts[1] += len(data)
                for k, name in enumerate(names):  # an event's name split between two reads is counted once
                    counts[2 + k] += (key.data["tail"][-(len(name) - 1) :] + data).count(name)
                key.data["tail"] = (key.data["tail"] + data)[-32:]
                if key.data["head"] is not None:
                    key.data["head"] += data
                    if key.data["head"].startswith(b"HTTP/1.1 200"):
                        counts[0] += 1
                        key.data["head"] = None
        for key in list(selector.get_map().values()):
            key.fileobj.close()

    def close(self) -> None:
        self.stop.set()
        self.reader.join(timeout=30)


def stream_load(port: int, pid: int, probe: str, scene: dict, workers: int, n: int, seconds: float = 20.0) -> dict:
    """`n` open event streams on fresh renders of `scene` (one running on each worker and one queued: half of
    the streams on each of the first and the last); for `seconds`, one client alternates GET /api/jobs/{probe}
    and GET /api/health: their latencies, the events the streams received, and the API process's CPU meanwhile.
    Fresh renders for each `n`, so that each measure meets the same passes (a pass has twice the samples of the
    one before it: a render's bands, and so its progress events, come slower and slower)."""
    api = Api(port)
    renders = [api.json("POST", "/api/jobs", {"scene": scene})["id"] for _ in range(workers + 1)]
    deadline = time.monotonic() + 180  # after the lesson panels the server renders ahead at its start
    while api.json("GET", f"/api/jobs/{renders[0]}")["status"] != "running":
        if time.monotonic() > deadline:
            raise RuntimeError("the render followed did not start in time")
        time.sleep(0.05)
    followed = [renders[0], renders[-1]]  # a running render's stream, and a queued one's: both are followed
    streams = Streams(port, followed, n)
    deadline = time.monotonic() + 30
    while streams.opened < n and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(1.0)  # the streams settled
    gets, healths = [], []
    events0 = dict(streams.events)
    cpu0, t0 = cpu_seconds(pid), time.monotonic()
    while time.monotonic() - t0 < seconds:
        for path, out in ((f"/api/jobs/{probe}", gets), ("/api/health", healths)):
            t = time.perf_counter()
            status, _ = api.call("GET", path)
            out.append((time.perf_counter() - t) * 1000)
            assert status == 200, (path, status)
        time.sleep(0.01)
    elapsed = time.monotonic() - t0
    cores = (cpu_seconds(pid) - cpu0) / elapsed
    events = {kind: round((streams.events[kind] - events0[kind]) / elapsed, 1) for kind in streams.events}
    rendering = api.json("GET", f"/api/jobs/{renders[0]}")["status"] == "running"
    opened, received = streams.opened, streams.bytes
    streams.close()
    for job_id in renders:
        api.call("DELETE", f"/api/jobs/{job_id}")
    for job_id in renders:  # the worker free again before the next measure
        wait_done(api, job_id, timeout=60)
    api.close()
    load = Path("/proc/loadavg").read_text().strip()
    return {"streams": n, "opened": opened, "bytes": received, "events_per_s": events,
            "get_ms": percentiles(gets), "health_ms": percentiles(healths), "api_cores": cores, "load": load,
            "still_rendering": rendering}  # fmt: skip


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="bench.service", description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=5, help="submissions per first-preview measurement")
    p.add_argument("--requests", type=int, default=2000, help="GET requests per latency loop")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--validate-only", action="store_true", help="only the validations of 25 000 spheres")
    p.add_argument("--streams", help="only open event streams while rendering: their numbers, e.g. 50,100,200,500")
    p.add_argument("--seconds", type=float, default=20.0, help="seconds of GETs for each number of streams")
    p.add_argument("--redis", action="store_true", help="the Redis backend: a redis-server and worker hosts here")
    p.add_argument("--api-cpus", help="the API on these cores (e.g. 0), and this benchmark, the workers and Redis on "
                   "the others: as if the clients and the worker hosts were machines of their own")  # fmt: skip
    args = p.parse_args(argv)
    if args.api_cpus:
        if not args.redis:
            p.error("--api-cpus needs --redis (the embedded backend's workers are the API's own processes)")
        API_CPUS[:] = sorted({int(c) for c in args.api_cpus.split(",")})
        others = set(os.sched_getaffinity(0)) - set(API_CPUS)
        if not others:
            p.error("--api-cpus: leave at least one core to the rest")
        os.sched_setaffinity(0, others)  # inherited by the redis-server, the worker hosts and the stream reader

    cornell = json.loads((SCENES / "cornell.json").read_text())
    assert (cornell["film"]["width"], cornell["film"]["height"]) == (256, 256)
    long = json.loads((SCENES / "whitted.json").read_text())
    long["film"].update(width=256, height=256)
    long["sampler"] = {"type": "jittered", "spp": 4096}

    results: dict = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}",
    }
    if API_CPUS:
        results["api_cpus"] = API_CPUS
    with tempfile.TemporaryDirectory(prefix="bench-service-") as tmp:
        data = Path(tmp) / "data"
        redis_url = None
        if args.redis:
            redis_url = start_redis()
            results["backend"] = "redis"
        t_start = time.perf_counter()
        proc, port = start_server(data, args.workers, redis_url)
        results["server_start_s"] = time.perf_counter() - t_start
        try:
            api = Api(port)
            warm = api.json("POST", "/api/jobs", {"scene": cornell})["id"]
            wait_done(api, warm)  # warm: one job rendered
            if args.validate_only:
                results["validate_load"] = validate_load(port, warm)
                api.close()
                return _finish(results, args)
            if args.streams:
                results["stream_load"] = [
                    stream_load(port, proc.pid, warm, long, args.workers, int(n), args.seconds)
                    for n in args.streams.split(",")
                ]
                api.close()
                return _finish(results, args)

            events = [first_preview_by_events(port, cornell) for _ in range(args.runs)]
            polled = [first_preview_by_polling(port, cornell) for _ in range(args.runs)]
            results["first_preview_event_s"] = sorted(e[0] for e in events)
            results["first_preview_png_s"] = sorted(e[1] for e in events)
            results["first_preview_polled_s"] = sorted(polled)
            job = api.json("GET", f"/api/jobs/{events[0][2]}")
            results["cornell_render_s"] = job["elapsed"]

            probe = api.json("POST", "/api/jobs", {"scene": cornell})["id"]
            wait_done(api, probe)
            results["get_idle_ms"] = percentiles(get_loop(port, probe, args.requests))
            results["raytree_load"] = raytree_load(port, probe)
            results["validate_load"] = validate_load(port, probe)

            busy = [api.json("POST", "/api/jobs", {"scene": long})["id"] for _ in range(args.workers + 1)]
            while api.json("GET", "/api/health")["jobs"]["running"] < args.workers:
                time.sleep(0.05)
            time.sleep(1.0)  # well into the render
            results["get_busy_ms"] = percentiles(get_loop(port, probe, args.requests))
            results["get_busy_8_clients_ms"] = percentiles(concurrent_get_loops(port, probe, 8, args.requests // 8))
            health = api.json("GET", "/api/health")
            results["still_rendering"] = health["jobs"]["running"] == args.workers
            for job_id in busy:
                api.call("DELETE", f"/api/jobs/{job_id}")
            api.close()
        finally:
            proc.terminate()
            proc.wait(timeout=30)
            stop_helpers()

    return _finish(results, args)


def _finish(results: dict, args) -> dict:
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        report(results)
    return results


def report(r: dict) -> None:
    def s(xs: list[float]) -> str:
        return f"median {statistics.median(xs) * 1000:.0f} ms (min {min(xs) * 1000:.0f}, max {max(xs) * 1000:.0f})"

    def lat(d: dict) -> str:
        return (
            f"p50 {d['p50']:.2f} ms, p90 {d['p90']:.2f} ms, p99 {d['p99']:.2f} ms, max {d['max']:.2f} ms "
            f"({d['n']} requests)"
        )

    pinned = f"; the API on core(s) {r['api_cpus']}, the rest on the others" if r.get("api_cpus") else ""
    print(f"machine: {r['machine']}{pinned}")
    print(f"server start (kernels cached) until workers ready: {r['server_start_s']:.2f} s")
    for load in r.get("stream_load", []):  # --streams
        print(f"{load['streams']} event streams open ({load['opened']} answered, {load['bytes']} bytes of events), "
              f"API {load['api_cores']:.2f} cores, load {load['load']}")  # fmt: skip
        print(f"  GET /api/jobs/{{id}}: {lat(load['get_ms'])}")
        print(f"  GET /api/health:    {lat(load['health_ms'])}")
        rate = load["events_per_s"]
        print(f"  events received per second, over all streams: {rate['progress']:g} progress, "
              f"{rate['preview']:g} preview; the render still running at the end: "
              f"{load['still_rendering']}")  # fmt: skip
    if "stream_load" in r:
        return
    if "first_preview_event_s" not in r:  # --validate-only
        _report_validations(r["validate_load"], lat)
        return
    print(f"cornell 256x256, 16 spp, whole render in the worker: {r['cornell_render_s']:.2f} s")
    print(f"submit -> first preview event (SSE):   {s(r['first_preview_event_s'])}")
    print(f"submit -> first preview PNG in hand:   {s(r['first_preview_png_s'])}")
    print(f"submit -> first preview (polling 5 ms): {s(r['first_preview_polled_s'])}")
    print(f"GET /api/jobs/{{id}}, idle server:          {lat(r['get_idle_ms'])}")
    print(f"GET /api/jobs/{{id}}, rendering on all cores: {lat(r['get_busy_ms'])}")
    print(f"  the same from 8 concurrent clients:      {lat(r['get_busy_8_clients_ms'])}")
    print(f"renders still running at the end of the loop: {r['still_rendering']}")
    rt = r["raytree_load"]
    print(f"ray trees of the radiosity Cornell box: the first click {rt['first_click_s']:.2f} s (solves)")
    print(f"  6 clients clicking at once, each click: {lat(rt['click_ms'])}")
    print(f"  GET /api/jobs/{{id}} meanwhile:           {lat(rt['get_ms'])}")
    _report_validations(r["validate_load"], lat)


def _report_validations(v: dict, lat) -> None:
    print(f"validations of {v['spheres']} spheres ({v['body_bytes'] / 1e6:.2f} MB): one alone {v['alone_s']:.2f} s")
    print(f"  {v['clients']} clients validating at once, each:  {lat(v['validate_ms'])}")
    print(f"  GET /api/jobs/{{id}} meanwhile:           {lat(v['get_ms'])}")


if __name__ == "__main__":
    main()
