"""A class submitting in the same second, on the default settings (issue #32, item 9; docs/service.md, "Sizing").

    python -m bench.burst [--students 300] [--addresses own|one] [--backend embedded|redis] [--hosts 2]
        [--set NAME=VALUE ...] [--follow] [--json [FILE]]

The server is `python -m server` with nothing set but its instructor token (and a data directory): the
defaults a deployer gets. The instructor publishes the repository's example assignment (bench/grading.py's)
with its roster of `--students`; once its reference is graded, every student's client waits at one barrier,
then opens its connection and POSTs one submission (a copy of the example class's student `k mod 9`: scenes at
1 to 64 spp, broken JSON, schema errors, PNG and EXR renders) at the same instant.

- `--addresses own` (the default): student k connects from a loopback address of their own (127.0.1.x, ...), as
  a class on a campus network reaches a server; `one`: the whole class from 127.0.0.1, a class behind one NAT
  (the server is then told so, TRACER_SHARED_NETWORKS=127.0.0.1/32, as docs/service.md says to).
- `--set NAME=VALUE` sets a TRACER_ setting (a checklist's size), `--backend redis` runs the API alone
  (`--workers 0 --redis`) with `--hosts` worker hosts on this machine.
- `--follow`: each client then follows its submission's event stream to its final status (the time from the
  burst to the last student's feedback).

It reports every answer's status (the point: no 429 and no 503), the submit latency (to the 202), and with
--follow when each student had their grade: a table (accepted, refused by status, p50/p99, graded within), or
with `--json` the whole result as JSON instead (`--json FILE`: also written to FILE). Nothing here is a test;
tests/server/test_burst.py asserts the answers at 300 on loopback. Every process started here is stopped by its
PID (its process group) at the end.
"""

from __future__ import annotations

import argparse
import base64
import collections
import http.client
import json
import os
import platform
import secrets
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

from bench.cluster import Procs, start_api, start_redis, wait
from bench.deadline import FINAL, follow, pct, publish, roster_csv
from bench.grading import class_names, submission_file
from bench.service import Api
from server.course import command


def address(k: int) -> str:
    """Student k's own loopback address: 127.0.1.1, ... 127.0.1.250, 127.0.2.1, ..."""
    return f"127.0.{1 + k // 250}.{1 + k % 250}"


def body_of(k: int, what: str) -> bytes:
    """Student k's submission as the page posts it (a scene as text, or an image in base64); for a render or a
    validation, their scene as an object (a valid one of the class's, whatever their own submission is)."""
    names = class_names()
    if what != "submit":
        valid = ("alice", "bob", "dave", "erin")  # the class's valid scenes, at 1 to 64 spp
        return json.dumps({"scene": json.loads(submission_file(k, valid[k % len(valid)])[1])}).encode()
    name, data = submission_file(k, names[k % len(names)])
    if name.endswith(".json"):
        return json.dumps({"scene": data.decode()}).encode()
    return json.dumps({"image": base64.b64encode(data).decode(), "format": name.rsplit(".", 1)[1]}).encode()


class Student(threading.Thread):
    """One client: wait at the barrier, connect, POST, (follow to the final status). It connects after the
    barrier: a connection opened before it sits idle while the other clients start, and on a loaded machine the
    server's header timeout closes it (234 of 300 broken pipes in an independent run, issue #39)."""

    def __init__(self, k, port, aid, token, body, source, barrier, follow, what):
        super().__init__(daemon=True)
        self.path = {
            "submit": f"/api/assignments/{aid}/submissions",
            "render": "/api/jobs",
            "validate": "/api/validate",
        }[what]
        self.ok = 200 if what == "validate" else 202
        self.k, self.port, self.aid, self.token, self.body = k, port, aid, token, body
        self.source, self.barrier, self.follow = source, barrier, follow
        self.code = self.latency = self.final = self.status = self.error = self.sid = self.score = None
        self.sent = self.wall = None
        self.statuses: list[str] = []  # what its event stream showed (bench.deadline's `follow` fills these)

    def run(self) -> None:
        headers = {"Authorization": f"Bearer {self.token}", "Content-Type": "application/json"}
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=300, source_address=(self.source, 0))
        try:
            self.barrier.wait(timeout=120)
            self.sent, self.wall = time.perf_counter(), time.time()
            conn.connect()
            conn.request("POST", self.path, body=self.body, headers=headers)
            r = conn.getresponse()
            data = r.read()
            self.code, self.latency = r.status, time.perf_counter() - self.sent
            if r.status != self.ok:
                self.error = f"{r.status} {data[:160]!r}"
                return
            if self.follow and self.ok == 202 and "/submissions" in self.path:
                self.sid = json.loads(data)["id"]
                if not follow(conn, self.aid, self, headers) and self.error is None:
                    self.error = "its event stream ended before a final status"
        except (OSError, http.client.HTTPException, threading.BrokenBarrierError) as e:
            self.error = f"{type(e).__name__}: {e}"
        finally:
            conn.close()


def run(args, root: Path) -> dict:
    token = secrets.token_urlsafe(24)
    env = {**os.environ, "TRACER_INSTRUCTOR_TOKEN": token}
    if args.addresses == "one":
        env["TRACER_SHARED_NETWORKS"] = "127.0.0.1/32"
    for item in args.set:
        name, _, value = item.partition("=")
        env[name if name.startswith("TRACER_") else "TRACER_" + name.upper()] = value
    procs = Procs(root)
    try:
        if args.backend == "redis":
            _, url = start_redis(procs)
            api = start_api(procs, root / "data", ["--workers", "0", "--redis", url], env)
            for h in range(args.hosts):
                procs.start(f"host{h}", [sys.executable, "-m", "server.worker", "--redis", url, "--name", f"host-{h}"],
                            env)  # fmt: skip
            wait(lambda: len(api.json("GET", "/api/health")["workers"]) == args.hosts, 180, "the worker hosts")
        else:
            api = start_api(procs, root / "data", [], env)
        health = api.json("GET", "/api/health")
        server = f"http://127.0.0.1:{api.port}"
        a = publish(server, token, time.time() + 86400)
        aid = a["id"]
        students = command.Client(server, token).json("POST", f"/api/assignments/{aid}/roster",
                                                      roster_csv(args.students), "text/csv")["students"]  # fmt: skip
        teacher = Api(api.port, token)
        wait(lambda: (teacher.json("GET", f"/api/assignments/{aid}")["reference_grade"] or {}).get("status")
             in FINAL, 600, "the reference scene's grade", 0.2)  # fmt: skip
        bodies = [body_of(k, args.what) for k in range(args.students)]
        barrier = threading.Barrier(args.students + 1)
        threading.stack_size(512 * 1024)
        clients = [Student(k, api.port, aid, students[k]["token"], bodies[k],
                           address(k) if args.addresses == "own" else "127.0.0.1", barrier, args.follow, args.what)
                   for k in range(args.students)]  # fmt: skip
        for c in clients:
            c.start()
        load0 = Path("/proc/loadavg").read_text().split()[:3]
        barrier.wait(timeout=120)
        t0 = time.perf_counter()
        for c in clients:
            c.join(timeout=max(1.0, t0 + args.timeout - time.perf_counter()))
        took = time.perf_counter() - t0
        codes = collections.Counter(str(c.code) for c in clients)
        errors = collections.Counter(c.error[:120] for c in clients if c.error)
        finals = [c.final - c.wall for c in clients if c.final is not None]  # follow's time.time() at the grade
        teacher.close()
        return {
            "students": args.students,
            "what": args.what,
            "addresses": args.addresses,
            "backend": args.backend,
            "set": args.set,
            "workers": len(health.get("workers", [])),
            "checkers": len(health.get("checkers", []))
            if isinstance(health.get("checkers"), list)
            else health.get("checkers"),
            "codes": dict(codes),
            "errors": dict(errors.most_common(5)),
            "submit_latency_s": pct([c.latency for c in clients if c.latency is not None]),
            "feedback_s": pct(finals) if finals else None,
            "statuses": dict(collections.Counter(c.status for c in clients if c.status)),
            "took_s": round(took, 1),
            "load_before": load0,
            "load_after": Path("/proc/loadavg").read_text().split()[:3],
        }
    finally:
        procs.stop()


def summary(r: dict) -> str:
    """The result as a table for a person: what was accepted, what was refused (by status; `none`: no answer),
    the submit latency and, with --follow, when the class had its grades."""
    ok = sum(n for code, n in r["codes"].items() if code in ("200", "202"))
    refused = sorted((code, n) for code, n in r["codes"].items() if code not in ("200", "202"))
    rows = [("students", f"{r['students']} ({r['what']}, {r['backend']} backend, addresses {r['addresses']})")]
    rows.append(("accepted", f"{ok} of {r['students']}"))
    rows += [(f"refused {'none' if code == 'None' else code}", str(n)) for code, n in refused]
    rows += [("error", f"{n} x {text}") for text, n in r.get("errors", {}).items()]
    lat = r["submit_latency_s"]
    rows.append(("submit p50 / p99", f"{lat['p50']:.2f} / {lat['p99']:.2f} s" if lat.get("n") else "-"))
    fb = r.get("feedback_s")
    if fb:
        graded = ", ".join(f"{n} {status}" for status, n in sorted(r.get("statuses", {}).items()))
        rows.append(
            ("graded within", f"p50 {fb['p50']:.1f} s, p99 {fb['p99']:.1f} s, last {fb['max']:.1f} s ({graded})")
        )
    rows.append(("took", f"{r['took_s']} s, load {' '.join(r['load_before'])} -> {' '.join(r['load_after'])}"))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k.ljust(width)}  {v}" for k, v in rows)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="bench.burst", description=__doc__.split("\n\n")[0])
    p.add_argument("--students", type=int, default=300)
    p.add_argument(
        "--what",
        choices=("submit", "render", "validate"),
        default="submit",
        help="POST a submission, a render of their scene (/api/jobs) or a validation of it (/api/validate)",
    )
    p.add_argument("--addresses", choices=("own", "one"), default="own")
    p.add_argument("--backend", choices=("embedded", "redis"), default="embedded")
    p.add_argument("--hosts", type=int, default=2)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a TRACER_ setting")
    p.add_argument("--follow", action="store_true", help="follow every submission to its final status")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds to wait for the clients")
    p.add_argument(
        "--json",
        nargs="?",
        const="-",
        metavar="FILE",
        help="print the results as JSON instead of the table (and write them to FILE if given)",
    )
    p.add_argument("--logs", type=Path, help="keep the servers' logs in this folder")
    args = p.parse_args(argv)
    print(f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-burst-") as tmp:
        try:
            result = run(args, Path(tmp))
        finally:
            if args.logs:  # the servers' logs, kept
                args.logs.mkdir(parents=True, exist_ok=True)
                for log in Path(tmp).glob("*.log"):
                    shutil.copy(log, args.logs / log.name)
    if args.json is None:
        print(summary(result))
        return result
    print(json.dumps(result, indent=2))
    if args.json != "-":
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
