"""Load test of the rendering service: a class submitting at once (docs/service.md, "A class at once").

    python -m bench.load [--students 200] [--workers 1] [--restart] [--redis] [--json]

It starts `python -m server` on 127.0.0.1 with a fresh data directory and an instructor token, then
`--students` clients, each with a token of its own, submit a small scene at the same moment (one
thread each, released together by a barrier) and follow their job until it ends. It reports
- every submission's answer (202, or what else) and its latency;
- whether each student's list (`GET /api/jobs` with the student's token) holds exactly that student's job,
  and another student's token gets 404 for it;
- how long until every job ended, and whether each ended `done` with a PNG;
- the latency of `GET /api/jobs/{id}` read meanwhile by one more client;
- with `--restart`: the server is stopped by SIGTERM to its process group once every job is queued,
  and started again on the same data directory; every job must still end `done`.

`--redis` runs it on the Redis backend: a redis-server, the API alone and `--workers` worker hosts (niced),
all on this machine (bench.service's); a restart restarts the API alone, the hosts stay.

A job is lost when its submission was answered 202 and it is then missing, or does not end `done`.
Nothing here is a test: the numbers go in docs/service.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import secrets
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path

from bench.service import Api, free_port, percentiles, start_redis, start_server, stop_helpers

ROOT = Path(__file__).resolve().parent.parent
INSTRUCTOR = "bench-load-instructor-" + secrets.token_urlsafe(16)


ENV = {
    "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR,
    "TRACER_MAX_QUEUED_JOBS": "1000",
    "TRACER_SHARED_NETWORKS": "127.0.0.1",  # the whole class on one address: a class behind one NAT
}


def start(data_dir: Path, port: int, workers: int, redis_url: str | None, hosts: bool = True) -> subprocess.Popen:
    """`python -m server` with the instructor's token, in a process group of its own (bench.service)."""
    return start_server(data_dir, workers, redis_url, port=port, env=ENV, token=INSTRUCTOR, hosts=hosts)[0]


def stop(proc: subprocess.Popen) -> float:
    """SIGTERM to the server's process group; seconds until it exited."""
    t = time.perf_counter()
    os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        raise RuntimeError("the server did not stop within 60 s of SIGTERM") from None
    return time.perf_counter() - t


def tiny_scene(k: int) -> dict:
    """A student's scene: the whitted example at 48 x 36, 1 or 4 samples, its own seed."""
    scene = json.loads((ROOT / "scenes" / "whitted.json").read_text())
    scene["film"].update(width=48, height=36)
    scene["sampler"] = {"type": "jittered", "spp": 4 if k % 2 else 1}
    scene.setdefault("render", {})["seed"] = k
    scene["name"] = f"student {k}"
    return scene


def run(students: int, workers: int, restart: bool, redis: bool = False) -> dict:
    results: dict = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}",
        "students": students,
        "workers": workers,
        "backend": "redis" if redis else "embedded",
    }
    with tempfile.TemporaryDirectory(prefix="bench-load-") as tmp:
        data = Path(tmp) / "data"
        data.mkdir()
        port = free_port()
        redis_url = start_redis() if redis else None
        proc = None
        try:
            proc = start(data, port, workers, redis_url)
            teacher = Api(port, INSTRUCTOR)
            warm = teacher.json("POST", "/api/jobs", {"scene": tiny_scene(0)})["id"]
            while not teacher.json("GET", f"/api/jobs/{warm}")["finished"]:
                time.sleep(0.05)

            tokens = [f"student-{k:03d}-" + secrets.token_urlsafe(12) for k in range(students)]
            bodies = [json.dumps({"scene": tiny_scene(k)}).encode() for k in range(students)]
            answers: list = [None] * students
            barrier = threading.Barrier(students + 1)

            def submit(k: int) -> None:
                api = Api(port, tokens[k])
                api.conn.connect()  # connected before the barrier: the requests leave together
                barrier.wait()
                t = time.perf_counter()
                status, body = api.call("POST", "/api/jobs", bodies[k])
                answers[k] = (status, (time.perf_counter() - t) * 1000, json.loads(body))
                api.close()

            gets: list[float] = []
            reading = threading.Event()

            def reader() -> None:
                api = Api(port, INSTRUCTOR)
                while not reading.is_set():
                    t = time.perf_counter()
                    try:
                        status, _ = api.call("GET", f"/api/jobs/{warm}")
                    except OSError:  # the server is restarting (--restart)
                        status = None
                        time.sleep(0.2)
                    if status == 200:
                        gets.append((time.perf_counter() - t) * 1000)
                    time.sleep(0.01)
                api.close()

            threads = [threading.Thread(target=submit, args=(k,)) for k in range(students)]
            for t in threads:
                t.start()
            probe = threading.Thread(target=reader)
            probe.start()
            barrier.wait()
            t0 = time.perf_counter()
            for t in threads:
                t.join(timeout=300)
            results["all_answered_s"] = time.perf_counter() - t0
            statuses: dict[str, int] = {}
            for a in answers:
                key = "no answer" if a is None else str(a[0])
                statuses[key] = statuses.get(key, 0) + 1
            results["submit_statuses"] = statuses
            results["refused"] = [a[2] for a in answers if a is not None and a[0] != 202][:3]
            results["submit_ms"] = percentiles([a[1] for a in answers if a is not None])
            ids = [a[2]["id"] if a is not None and a[0] == 202 else None for a in answers]

            if restart:
                results["stop_s"] = stop(proc)
                t = time.perf_counter()
                proc = start(data, port, workers, redis_url, hosts=False)  # the worker hosts stayed
                results["restart_s"] = time.perf_counter() - t

            deadline = time.monotonic() + 30 * 60
            ended: dict[str, dict] = {}
            mine = {i for i in ids if i}  # the students' jobs (the warm-up's and the previews' end too)
            while not mine <= ended.keys() and time.monotonic() < deadline:
                for row in teacher.json("GET", "/api/jobs?limit=1000&scope=all")["jobs"]:
                    if row["finished"]:
                        ended[row["id"]] = row
                time.sleep(0.5)
            results["all_ended_s"] = time.perf_counter() - t0
            reading.set()
            probe.join()
            results["get_during_ms"] = percentiles(gets) if gets else None

            lost, not_done, own_list_wrong, foreign_seen, no_png = [], [], 0, 0, 0
            for k, job_id in enumerate(ids):
                if job_id is None:
                    continue
                row = ended.get(job_id)
                if row is None:
                    lost.append(job_id)
                    continue
                if row["status"] != "done":
                    not_done.append((job_id, row["status"], row.get("error")))
                if k % 10 == 0:  # every tenth student checks their list, their image and a neighbour's job
                    api = Api(port, tokens[k])
                    mine = api.json("GET", "/api/jobs")
                    own_list_wrong += [j["id"] for j in mine["jobs"]] != [job_id]
                    status, png = api.call("GET", f"/api/jobs/{job_id}/image")
                    no_png += not (status == 200 and png[:8] == b"\x89PNG\r\n\x1a\n")
                    other = ids[(k + 1) % students]
                    if other is not None:
                        foreign_seen += api.call("GET", f"/api/jobs/{other}")[0] != 404
                    api.close()
            results["accepted"] = sum(1 for i in ids if i)
            results["lost"] = lost
            results["not_done"] = not_done
            results["own_list_wrong"] = own_list_wrong
            results["foreign_job_seen"] = foreign_seen
            results["image_missing"] = no_png
            health = teacher.json("GET", "/api/health")
            results["jobs_by_status"] = health["jobs"]
            results["worker_restarts"] = sum(w.get("restarts", 0) for w in health["workers"])
            teacher.close()
        finally:
            if proc is not None and proc.poll() is None:
                results.setdefault("final_stop_s", stop(proc))
            stop_helpers()
    return results


def report(r: dict) -> None:
    def lat(d: dict | None) -> str:
        return "none" if not d else f"p50 {d['p50']:.1f} ms, p99 {d['p99']:.1f} ms, max {d['max']:.1f} ms"

    print(f"machine: {r['machine']}; {r['students']} students at once, {r['workers']} worker(s), {r['backend']}")
    answered = f"all answered in {r['all_answered_s']:.2f} s"
    print(f"submissions: {r['submit_statuses']}, {answered}; latency {lat(r['submit_ms'])}")
    if r["refused"]:
        print(f"refused: {r['refused']}")
    if "stop_s" in r:
        print(f"SIGTERM to the server's group: stopped in {r['stop_s']:.2f} s, started again in {r['restart_s']:.2f} s")
    print(f"every job ended {r['all_ended_s']:.1f} s after the submissions")
    print(f"GET /api/jobs/{{id}} meanwhile: {lat(r['get_during_ms'])}")
    print(f"accepted {r['accepted']}, lost {len(r['lost'])}, not done {len(r['not_done'])} {r['not_done'][:3]}")
    print(f"students' own lists wrong: {r['own_list_wrong']}, another's job readable: {r['foreign_job_seen']}, "
          f"image missing: {r['image_missing']} (of every tenth student)")  # fmt: skip
    print(f"jobs by status at the end: {r['jobs_by_status']}; worker restarts {r['worker_restarts']}")


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="bench.load", description=__doc__.split("\n\n")[0])
    p.add_argument("--students", type=int, default=200, help="clients submitting at once, one token each")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--restart", action="store_true", help="SIGTERM the server's group once all are queued, restart")
    p.add_argument("--redis", action="store_true", help="the Redis backend: a redis-server and worker hosts here")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    r = run(args.students, args.workers, args.restart, args.redis)
    print(json.dumps(r, indent=1)) if args.json else report(r)
    return r


if __name__ == "__main__":
    main()
