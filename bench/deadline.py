"""Benchmark of a class at the deadline (docs/assignments.md, issue #23): a roster of students each submitting
one to three times in the last minutes before an assignment's deadline, on the Redis backend with worker
hosts or on the embedded one.

    python -m bench.deadline [--backend redis|embedded] [--students 300] [--window 60] [--hosts 2]
        [--kill-host] [--quick] [--seed 1] [--json FILE] [--keep DIR]

1. The class: student k is the example's student `k mod 9` (scenes/grading/class, made as bench/grading.py
   makes a class: alice's, bob's, dave's and erin's scenes at 1, 4, 16 or 64 spp with small changes,
   carol's broken JSON, frank's schema errors, ivan's wrong-size PNG, grace's and heidi's own renders as
   PNG or EXR); each makes 1, 2 or 3 submissions (40 / 35 / 25 %), each a fresh copy.
2. **Time compressed**: the class's last five minutes are played in `--window` seconds of wall time (60 s:
   five times faster). `python -m server` keeps the wall clock (its clock is settable only in-process, for
   the tests), so it is the submissions that are compressed: each one's time is drawn uniformly in the
   window, which ends 5 s before the deadline. The assignment is published `--lead` seconds before the
   deadline, and the burst waits for its reference scene's grade (as an instructor publishes days
   before: the reference mean is rendered; the students' noise baselines are rendered when the first
   submission of their spp comes, in the burst).
3. The service: `--backend redis`: a redis-server, the API (`python -m server --workers 0 --redis URL`)
   and `--hosts` worker hosts (`python -m server.worker --threads 1`), as bench/cluster.py starts them;
   `--backend embedded`: `python -m server --workers 2` (one thread each). Each submission is one thread of
   this process: at its time it POSTs the submission with its student's token (the submit latency: to
   the 202), then follows its event stream (`.../submissions/{sid}/events`, as the page does) to its
   final status (submit-to-feedback: from the POST to that event). `--kill-host` (Redis): at the middle
   of the window, the first moment it is rendering, one worker host dies: SIGKILL of its process group
   and of its work horses (RQ runs each in a session of its own), so its try is lost (after the API's
   TRACER_LOST_AFTER, 15 s by default) and runs again on the other host; the dead host stays dead.
4. Counted from the server's rows at the end (the database and the instructor's list), not from what
   the clients saw: every acknowledged submission has its row, one row in its version's grading run
   and (a scene that validates) one render job; `lost` and `graded twice` must be 0. The profile splits
   a graded scene's time by its rows: accepted -> its render job queued (prepare, in a grading process)
   -> started (the batch lane's queue) -> finished (the render on a worker) -> the client's final event
   (the metrics in a grading process, the row, the event); and the worker time by render kind (the
   reference's, the baselines', the students').

Network: loopback only. Every process started here is stopped by its PID (its process group) at the end,
also on failure.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import platform
import random
import secrets
import signal
import sqlite3
import statistics
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

from bench.cluster import Procs, start_api, start_redis, wait
from bench.grading import EXAMPLE, class_names, submission_file, tree_cpu
from bench.service import Api
from server.course import command

FINAL = ("graded", "invalid", "failed")
MARGIN = 5.0  # seconds between the window's end and the deadline (a late acknowledgement is still on time)
ATTEMPTS = ((1, 0.40), (2, 0.35), (3, 0.25))  # submissions per student, with their shares


@dataclass
class Submission:
    """One planned submission and what its client saw (times: time.time(), this machine's clock as the server's)."""

    student: int
    at: float  # seconds into the window
    base: str  # the example student it copies
    name: str  # its file's name in a class's zip
    body: bytes  # the POST's JSON body
    kind: str  # scene, png or exr
    sent: float | None = None
    acked: float | None = None
    code: int | None = None
    sid: str | None = None
    final: float | None = None
    status: str | None = None
    score: float | None = None
    statuses: list[str] = field(default_factory=list)  # every status its event stream showed, in order
    error: str | None = None


def plan(students: int, window: float, seed: int) -> list[Submission]:
    """Each student's 1-3 submissions at uniform times in the window, each a fresh copy of their example."""
    import base64

    rng = random.Random(seed)
    names = class_names()
    subs, i = [], 0
    for k in range(students):
        base = names[k % len(names)]
        n = rng.choices([a for a, _ in ATTEMPTS], weights=[w for _, w in ATTEMPTS])[0]
        for at in sorted(rng.uniform(0, window) for _ in range(n)):
            name, data = submission_file(i, base)
            i += 1
            if name.endswith(".json"):
                kind, body = "scene", {"scene": data.decode()}  # as text: broken JSON stays broken
            else:
                kind = name.rsplit(".", 1)[1]
                body = {"image": base64.b64encode(data).decode(), "format": kind}
            subs.append(Submission(k, at, base, name, json.dumps(body).encode(), kind))
    return sorted(subs, key=lambda s: s.at)


def roster_csv(students: int) -> bytes:
    rows = "".join(f"s{k:03d},Student {k},s{k:03d}@example.edu\n" for k in range(students))
    return ("id,name,email\n" + rows).encode()


# -- the clients ------------------------------------------------------------------------------------


def run_submission(port: int, aid: str, token: str, sub: Submission, t0: float) -> None:
    """At its time: POST it, then follow its event stream to its final status."""
    time.sleep(max(0.0, t0 + sub.at - time.time()))
    headers = {"Authorization": f"Bearer {token}", "Content-Type": "application/json"}
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    try:
        sub.sent = time.time()
        conn.request("POST", f"/api/assignments/{aid}/submissions", body=sub.body, headers=headers)
        r = conn.getresponse()
        data = r.read()
        sub.acked, sub.code = time.time(), r.status
        if r.status != 202:
            sub.error = f"{r.status} {data[:200]!r}"
            return
        sub.sid = json.loads(data)["id"]
        for _ in range(3):  # a dropped stream (a stopping server) is opened again
            if follow(conn, aid, sub, headers):
                return
            conn.close()
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        sub.error = "its event stream never reached a final status"
    except (OSError, http.client.HTTPException) as e:
        sub.error = f"{type(e).__name__}: {e}"
    finally:
        conn.close()


def follow(conn: http.client.HTTPConnection, aid: str, sub: Submission, headers: dict) -> bool:
    """Read the submission's Server-Sent Events until its final status (True), or until the stream ends."""
    conn.request("GET", f"/api/assignments/{aid}/submissions/{sub.sid}/events", headers=headers)
    r = conn.getresponse()
    if r.status != 200:
        sub.error = f"events: {r.status} {r.read()[:200]!r}"
        return True
    event = None
    while True:
        line = r.readline()
        if not line:
            return False
        line = line.decode().rstrip("\r\n")
        if line.startswith("event:"):
            event = line.split(":", 1)[1].strip()
        elif line.startswith("data:") and event == "submission":
            view = json.loads(line.split(":", 1)[1])
            sub.statuses.append(view["status"])
            if view["status"] in FINAL and sub.final is None:
                sub.final, sub.status, sub.score = time.time(), view["status"], view["score"]
        elif line.startswith("data:") and event == "end":
            return sub.final is not None


# -- the service ------------------------------------------------------------------------------------


def start_service(args, procs: Procs, root: Path, token: str) -> tuple[Api, dict]:
    """The API (and Redis and the worker hosts); the API's client, and the processes by role."""
    env = {**os.environ, "TRACER_INSTRUCTOR_TOKEN": token, "TRACER_PREVIEWS_AHEAD": "0"}
    env["TRACER_SHARED_NETWORKS"] = "127.0.0.1/32"  # the whole class follows its streams from this one address
    roles: dict = {"hosts": []}
    if args.backend == "redis":
        _, url = start_redis(procs)
        roles["redis"] = procs.procs[-1][0]
        api = start_api(procs, root / "data", ["--workers", "0", "--redis", url], env)
        roles["api"] = procs.procs[-1][0]
        for k in range(args.hosts):
            argv = [sys.executable, "-m", "server.worker", "--redis", url, "--threads", "1", "--name", f"host-{k}"]
            roles["hosts"].append(procs.start(f"host{k}", argv, env))
        wait(lambda: len(api.json("GET", "/api/health")["workers"]) == args.hosts, 180, f"{args.hosts} worker hosts")
    else:
        api = start_api(procs, root / "data", ["--workers", "2"], {**env, "TRACER_RENDER_THREADS": "1"})
        roles["api"] = procs.procs[-1][0]
        wait(lambda: all(w["ready"] for w in api.json("GET", "/api/health")["workers"]), 180, "the render workers")
        roles["workers"] = [w["pid"] for w in api.json("GET", "/api/health")["workers"]]
    return api, roles


def publish(server: str, token: str, deadline: float) -> dict:
    """The repository's assignment through the instructor's command's own client (its reference file beside it)."""
    iso = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(deadline))
    args = SimpleNamespace(spec=str(EXAMPLE / "assignment.json"), deadline=iso, late_until=None, late_penalty=None,
                           max_submissions=3, counts="best", feedback=None, starter=None, show_reference=True,
                           open=False)  # fmt: skip
    body, ctype = command.multipart(*command.publish_parts(args))
    return command.Client(server, token).json("POST", "/api/assignments", body, ctype)


def kill_host(proc) -> list[int]:
    """A worker host dies: SIGKILL of its process group, and of its descendants (RQ's work horse runs in a
    session of its own); the pids killed."""
    pids = sorted(tree_cpu(proc.pid))
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return pids


def rendering(data_dir: Path, host: str) -> bool:
    """Whether a job's running try is on `host` now (its row in the job store)."""
    db = sqlite3.connect(f"file:{data_dir / 'jobs.sqlite3'}?mode=ro", uri=True, timeout=5)
    try:
        rows = db.execute("SELECT tries FROM jobs WHERE status = 'running'").fetchall()
    finally:
        db.close()
    return any((t := json.loads(r[0] or "[]")) and t[-1].get("worker") == host for r in rows)


def cpu_of(roles: dict) -> dict[str, float]:
    """CPU seconds so far of each role's process tree, the children that ended included (a host's work horses;
    the API's grading processes and, on the embedded backend, its render workers)."""
    out = {"api": sum(tree_cpu(roles["api"].pid, waited=True).values())}
    if roles.get("workers"):  # the embedded render workers, apart from the API and its grading processes
        out["render workers"] = sum(sum(tree_cpu(pid, waited=True).values()) for pid in roles["workers"])
        out["api"] -= out["render workers"]
    for k, p in enumerate(roles["hosts"]):
        out[f"host-{k}"] = sum(tree_cpu(p.pid, waited=True).values())
    if "redis" in roles:
        out["redis"] = sum(tree_cpu(roles["redis"].pid, waited=True).values())
    t = os.times()
    out["clients"] = t.user + t.system
    return out


# -- the counts and the profile, from the server's rows -------------------------------------------


def pct(xs: list[float]) -> dict:
    if not xs:
        return {"n": 0}
    xs = sorted(xs)

    def q(p: float) -> float:
        return xs[min(len(xs) - 1, int(round(p / 100 * (len(xs) - 1))))]

    return {"n": len(xs), "p50": q(50), "p90": q(90), "p99": q(99), "max": xs[-1], "mean": statistics.fmean(xs)}


def server_counts(data_dir: Path, aid: str, run_id: str, subs: list[Submission], t0: float) -> dict:
    db = sqlite3.connect(f"file:{data_dir / 'jobs.sqlite3'}?mode=ro", uri=True)
    try:
        rows = {r[0]: r for r in db.execute("SELECT id, accepted_at, kind, handed FROM course_submissions "
                                            "WHERE assignment_id = ?", (aid,))}  # fmt: skip
        items: dict[str, list] = {}
        for r in db.execute("SELECT student, stage, status, job_id, prepare_seconds, metrics_seconds FROM "
                            "grading_items WHERE run_id = ?", (run_id,)):  # fmt: skip
            items.setdefault(r[0], []).append(r)
        jobs = {r[0]: r for r in db.execute(
            "SELECT id, name, created_at, started_at, finished_at, status, attempts, lost, host, tries FROM jobs "
            "WHERE name LIKE 'grading: %'")}  # fmt: skip
        renders = list(db.execute("SELECT key, job_id FROM grading_renders WHERE run_id = ?", (run_id,)))
    finally:
        db.close()
    by_name: dict[str, list] = {}
    for j in jobs.values():
        by_name.setdefault(j[1].removeprefix("grading: "), []).append(j)
    acked = [s for s in subs if s.code == 202]
    lost = [s.sid for s in acked if s.sid not in rows or len(items.get(s.sid, [])) != 1
            or items[s.sid][0][1] != "graded"]  # fmt: skip
    twice = [s.sid for s in acked if len(items.get(s.sid, [])) > 1 or len(by_name.get(s.sid, [])) > 1]
    reopened = [s.sid for s in acked if _moved_after_final(s.statuses)]  # as the student saw it

    # the profile of a graded scene: accepted -> queued -> started -> finished -> the client's final event
    phases: dict[str, list[float]] = {"prepare": [], "queue": [], "render": [], "after": []}
    retried = 0
    for s in acked:
        it = items.get(s.sid, [None])[0]
        if it is None or it[3] is None or it[3] not in jobs or s.final is None:
            continue
        j = jobs[it[3]]
        accepted = rows[s.sid][1]
        if None in (j[3], j[4]):
            continue
        phases["prepare"].append(j[2] - accepted)
        phases["queue"].append(j[3] - j[2])
        phases["render"].append(j[4] - j[3])
        phases["after"].append(s.final - j[4])
        retried += j[6] > 1
    kinds: dict[str, dict] = {}
    reference_jobs = {job_id: key for key, job_id in renders if job_id}
    for j in jobs.values():
        if j[0] in reference_jobs:
            kind = "reference mean" if reference_jobs[j[0]] == "mean" else "baselines"
        elif j[1].removeprefix("grading: ") in rows:
            kind = "students"
        else:
            continue
        k = kinds.setdefault(kind, {"jobs": 0, "worker_s": 0.0, "in_burst": 0})
        k["jobs"] += 1
        if j[3] is not None and j[4] is not None:
            k["worker_s"] += j[4] - j[3]
            k["in_burst"] += j[3] >= t0
    burst = [j for j in jobs.values() if j[3] is not None and j[4] is not None and j[3] >= t0]
    hosts: dict[str, int] = {}
    for j in burst:  # by the worker that ended each (the last try's: a host's name, an embedded worker's number)
        tries = json.loads(j[9] or "[]")
        who = str(tries[-1].get("worker")) if tries else "?"
        hosts[who] = hosts.get(who, 0) + 1
    span = max((j[4] for j in burst), default=t0) - t0  # the burst's renders: from its start to the last one's end
    halves = [it for sid in rows for it in items.get(sid, [])]
    return {
        "rows": len(rows), "acknowledged": len(acked), "lost": len(lost), "lost_ids": lost[:5],
        "graded_twice": len(set(twice) | set(reopened)), "twice_ids": sorted(set(twice) | set(reopened))[:5],
        "render_jobs": sum(len(by_name.get(sid, [])) for sid in rows), "retried_jobs": retried,
        "by_status": {st: sum(1 for sid in rows if items.get(sid) and items[sid][0][2] == st) for st in FINAL},
        "phases": {k: pct(v) for k, v in phases.items()}, "render_kinds": kinds, "jobs_by_host": hosts,
        "render_span_s": span, "render_busy_s": sum(j[4] - j[3] for j in burst),
        "prepare_s": sum(h[4] or 0 for h in halves), "metrics_s": sum(h[5] or 0 for h in halves),
    }  # fmt: skip


def _moved_after_final(statuses: list[str]) -> bool:
    """A status that moved again after a final one: graded twice, as the student saw it."""
    first = next((i for i, x in enumerate(statuses) if x in FINAL), None)
    return first is not None and any(x != statuses[first] for x in statuses[first + 1 :])


# -- one run ----------------------------------------------------------------------------------------


def run(args, root: Path) -> dict:
    subs = plan(args.students, args.window, args.seed)
    print(f"{args.backend}: {args.students} students, {len(subs)} submissions "
          f"({sum(s.kind == 'scene' for s in subs)} scenes, {sum(s.kind != 'scene' for s in subs)} images) "
          f"in {args.window:g} s", flush=True)  # fmt: skip
    token = secrets.token_urlsafe(24)
    procs = Procs(root)
    loads: list[float] = []
    try:
        api, roles = start_service(args, procs, root, token)
        server = f"http://127.0.0.1:{api.port}"
        deadline = time.time() + args.lead
        a = publish(server, token, deadline)
        aid, run_id = a["id"], a["run_id"]
        teacher = Api(api.port, token)
        students = command.Client(server, token).json("POST", f"/api/assignments/{aid}/roster",
                                                      roster_csv(args.students), "text/csv")["students"]  # fmt: skip
        tokens = [s["token"] for s in students]
        warm = time.time()
        wait(lambda: (teacher.json("GET", f"/api/assignments/{aid}")["reference_grade"] or {}).get("status")
             in FINAL, 600, "the reference scene's grade", 0.2)  # fmt: skip
        reference = teacher.json("GET", f"/api/assignments/{aid}")["reference_grade"]
        warm = time.time() - warm
        t0 = deadline - MARGIN - args.window
        if t0 < time.time():
            raise RuntimeError(f"the reference took {warm:.0f} s to grade: give a longer --lead than {args.lead:g}")
        threading.stack_size(512 * 1024)
        threads = [threading.Thread(target=run_submission, args=(api.port, aid, tokens[s.student], s, t0), daemon=True)
                   for s in subs]  # fmt: skip
        time.sleep(max(0.0, t0 - 1 - time.time()))
        cpu0 = cpu_of(roles)
        for t in threads:
            t.start()
        killed: list[int] = []
        stop = threading.Event()

        def sample_load() -> None:
            while not stop.wait(2.0):
                loads.append(float(Path("/proc/loadavg").read_text().split()[0]))

        sampler = threading.Thread(target=sample_load, daemon=True)
        sampler.start()
        if args.kill_host:  # at the middle of the window, once host-0 is rendering (bounded: the window's end)
            time.sleep(max(0.0, t0 + args.window / 2 - time.time()))
            while not rendering(root / "data", "host-0") and time.time() < t0 + args.window:
                time.sleep(0.05)
            killed = kill_host(roles["hosts"][0])
            print(f"  killed worker host host-0 at {time.time() - t0:.1f} s: pids {killed}", flush=True)
        give_up = t0 + args.window + args.timeout
        for t in threads:
            t.join(timeout=max(0.0, give_up - time.time()))
        stop.set()
        cpu = {k: v - cpu0.get(k, 0.0) for k, v in cpu_of(roles).items() if k in cpu0}
        views = teacher.json("GET", f"/api/assignments/{aid}/submissions")["submissions"]
        status, grades = teacher.call("GET", f"/api/assignments/{aid}/grades.csv")
        teacher.close()
    finally:
        procs.stop()
    acked = [s for s in subs if s.code == 202]
    done = [s for s in acked if s.final is not None]
    counts = server_counts(root / "data", aid, run_id, subs, t0)
    out = {
        "backend": args.backend, "students": args.students, "window_s": args.window,
        "hosts": args.hosts if args.backend == "redis" else None, "kill_host": args.kill_host,
        "killed_pids": killed, "submissions": len(subs), "reference_grade": reference, "warm_s": warm,
        "refused": [s.error for s in subs if s.code not in (202, None)][:5],
        "refused_n": sum(s.code not in (202, None) for s in subs),
        "client_errors": [s.error for s in acked if s.error][:5] + [s.error for s in subs if s.code is None][:5],
        "submit_ms": pct([(s.acked - s.sent) * 1000 for s in subs if s.acked is not None]),
        "feedback_s": pct([s.final - s.sent for s in done]),
        "feedback_by_kind_s": {k: pct([s.final - s.sent for s in done if (s.kind == "scene") == (k == "scenes")])
                               for k in ("scenes", "images")},  # fmt: skip
        "last_submission_to_last_grade_s": max(s.final for s in done) - max(s.acked for s in acked) if done else None,
        "burst_s": max(s.acked for s in acked) - t0 if acked else None,
        "late": sum(1 for v in views if v["late"]), "server_views": len(views),
        "not_final_in_views": sum(1 for v in views if v["status"] not in FINAL),
        "grades_rows": len(grades.decode().splitlines()) - 1 if status == 200 else None,
        "cpu_s": cpu, "load": {"mean": statistics.fmean(loads) if loads else None, "max": max(loads, default=None)},
        "server": counts,
    }  # fmt: skip
    return out


def report(r: dict) -> None:
    def lat(d: dict, unit: str, scale: float = 1.0) -> str:
        if not d.get("n"):
            return "none"
        digits = 2 if unit == "s" else 1
        return (f"p50 {d['p50'] * scale:.{digits}f} {unit}, p99 {d['p99'] * scale:.{digits}f} {unit}, "
                f"max {d['max'] * scale:.1f} {unit} ({d['n']})")  # fmt: skip

    c = r["server"]
    where = f"Redis, {r['hosts']} worker hosts" if r["backend"] == "redis" else "embedded, 2 render workers"
    print(f"\n{where}{', one host killed mid-burst' if r['kill_host'] else ''}: {r['students']} students, "
          f"{r['submissions']} submissions in {r['window_s']:g} s (acknowledged over {r['burst_s']:.1f} s); "
          f"the reference graded {r['reference_grade']['score']:g} / {r['reference_grade']['max_score']:g} "
          f"{r['warm_s']:.1f} s after publishing")  # fmt: skip
    print(f"  submit (POST to 202):   {lat(r['submit_ms'], 'ms')}; refused {r['refused_n']} {r['refused']}")
    print(f"  submit to feedback:     {lat(r['feedback_s'], 's')}")
    kinds = r["feedback_by_kind_s"]
    print(f"    scenes: {lat(kinds['scenes'], 's')}; images: {lat(kinds['images'], 's')}")
    print(f"  last submission to last grade: {r['last_submission_to_last_grade_s']:.1f} s")
    print(f"  server rows: {c['rows']} submissions for {c['acknowledged']} acknowledged; by status {c['by_status']}; "
          f"lost {c['lost']} {c['lost_ids']}, graded twice {c['graded_twice']} {c['twice_ids']}; "
          f"{c['render_jobs']} render jobs for them ({c['retried_jobs']} ran again); late {r['late']}; "
          f"grades.csv rows {r['grades_rows']}")  # fmt: skip
    p = c["phases"]
    print("  a graded scene's time (p50 / p99 s): " + "; ".join(
        f"{name} {p[k]['p50']:.2f} / {p[k]['p99']:.2f}" for k, name in (
            ("prepare", "accepted to queued (prepare)"), ("queue", "queued to started (batch lane)"),
            ("render", "the render"), ("after", "finished to feedback (metrics, event)"))
        if p[k].get("n")))  # fmt: skip
    print("  worker time by render: " + "; ".join(
        f"{k} {v['jobs']} jobs, {v['worker_s']:.1f} s ({v['in_burst']} in the burst)"
        for k, v in c["render_kinds"].items()))  # fmt: skip
    workers = r["hosts"] or 2
    busy = 100 * c["render_busy_s"] / max(1e-9, workers * c["render_span_s"])
    print(f"  the burst's renders: {c['render_busy_s']:.1f} s of worker time in {c['render_span_s']:.1f} s from the "
          f"window's start to the last render's end ({busy:.0f} % of {workers} workers); jobs by host "
          f"{c['jobs_by_host']}")  # fmt: skip
    print(f"  grading processes: prepare {c['prepare_s']:.1f} s, metrics {c['metrics_s']:.1f} s of process time")
    print("  CPU during the burst (s): " + ", ".join(f"{k} {v:.1f}" for k, v in r["cpu_s"].items()))
    if r["load"]["mean"] is not None:
        print(f"  load average (1 min) during the burst: mean {r['load']['mean']:.1f}, max {r['load']['max']:.1f}")
    if r["client_errors"]:
        print(f"  client errors: {r['client_errors']}")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> list[dict]:
    p = argparse.ArgumentParser(prog="bench.deadline", description=__doc__.split("\n\n")[0])
    p.add_argument("--backend", choices=("redis", "embedded"), default="redis")
    p.add_argument("--students", type=int, default=300)
    p.add_argument("--window", type=float, default=60.0, help="seconds of wall time for the last five minutes")
    p.add_argument("--hosts", type=int, default=2, help="worker hosts (Redis)")
    p.add_argument("--kill-host", action="store_true", help="kill one worker host at the middle of the window")
    p.add_argument("--quick", action="store_true", help="a small run: 12 students in 10 s")
    p.add_argument("--lead", type=float, help="seconds from publishing to the deadline (window + 45; --quick: + 20)")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds after the window to wait for the grades")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", help="write the results as JSON here")
    p.add_argument("--keep", type=Path, help="keep the data directories and logs here")
    args = p.parse_args(argv)
    if args.quick:
        args.students, args.window = min(args.students, 12), min(args.window, 10.0)
    if args.kill_host and (args.backend != "redis" or args.hosts < 2):
        p.error("--kill-host needs --backend redis and at least 2 --hosts (one to carry on)")
    args.lead = args.lead or args.window + (20.0 if args.quick else 45.0)
    from tracer.rendering.progressive import load_kernels

    load_kernels()  # the images of the class are rendered here
    print(f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"load average before: {Path('/proc/loadavg').read_text().split()[:3]}", flush=True)  # fmt: skip
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="bench-deadline-", dir=args.keep) as tmp:
        result = run(args, Path(tmp))
        if args.keep is not None:
            import shutil

            shutil.copytree(tmp, args.keep / Path(tmp).name.replace("bench-deadline-", "kept-"))
    report(result)
    print(f"load average after: {Path('/proc/loadavg').read_text().split()[:3]}")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return [result]


if __name__ == "__main__":
    main()
