"""Benchmark of grading a class through the service (docs/grading.md): where the time of a big class goes.

    python -m bench.grading [--students 300] [--workers 2] [--runs 1] [--keep DIR]

1. Makes a class of `--students` submissions from the example (scenes/grading/class): the nine students
   in turn, each copy varied: the scenes' samples (1, 4, 16 or 64 spp, so several noise baselines) and
   small changes of a colour or a light; the images re-rendered with other seeds (PNG, 16-bit PNG,
   half-float EXR), the wrong-size one as it is. Zipped like an instructor's class.
2. Starts `python -m server --workers W` on 127.0.0.1 with a fresh data directory, grades one student to
   warm it up (kernels loaded, the grading processes started), then uploads the class
   (POST /api/grade/upload) and follows the run until it is done.
3. Reads the split from the run's rows and its jobs (the database) and the workers' log:
   - renders: the time inside the renderer (the workers' "done, X s" lines), and each job's time in its
     worker (claim to finish: compiling the scene, the renderer, writing the image, EXR and AOVs);
   - the queue: the workers' idle time between the first render's start and the last one's end;
   - the grading processes: each student's two halves (prepare, metrics) and the tail after the last render;
   - the API: the upload (body, unpacking, the rows) until its 202.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import re
import shutil
import sqlite3
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from bench.service import Api, start_server

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "scenes" / "grading"
CLASS = EXAMPLE / "class"
SPP = (1, 4, 16, 64)  # the scenes' samples, in turn (jittered: perfect squares)


def assignment() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def render(scene: dict):
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.progressive import render as run
    from tracer.scene import load_scene

    return run(compile_scene(load_scene(scene)[0])).image


def class_names() -> list[str]:
    """The example class's nine students (their files' names without the suffix), in order."""
    return sorted(p.stem if p.is_file() else p.name for p in CLASS.iterdir())


def submission_file(i: int, base: str) -> tuple[str, bytes]:
    """The `i`-th copy of the example student `base`'s submission, a little different from the others: (its
    name in a class's zip, its bytes). bench/deadline.py submits them one by one."""
    import numpy as np

    from tracer.rendering.film import png_bytes

    names = class_names()
    who = f"{base}_{i:03d}"
    if base in ("alice", "bob", "dave", "erin"):
        scene = json.loads((CLASS / f"{base}.json").read_text())
        scene["sampler"] = {"type": "jittered", "spp": SPP[(i // len(names)) % len(SPP)]}
        scene["name"] = f"{who}'s scene"
        if base == "bob":
            scene["lights"][0]["intensity"] = 20 + i % 7  # another point light
        if base == "erin":
            scene["materials"]["red"] = {"kd": [0.1, 0.2, 0.5 + 0.01 * (i % 30)]}
        return f"hw4/{who}.json", json.dumps(scene, indent=1).encode()
    if base == "carol":  # broken JSON, broken differently
        return f"hw4/{who}.json", (CLASS / "carol.json").read_text().replace("5]", f"{i % 9}]").encode()
    if base == "frank":  # schema errors, in a folder
        return f"hw4/{who}/scene.json", (CLASS / "frank" / "scene.json").read_bytes()
    if base == "ivan":  # the wrong size, as it is
        return f"hw4/{who}.png", (CLASS / "ivan.png").read_bytes()
    # grace (right) and heidi (wrong): their own renders with another seed, in turn PNG, EXR
    scene = json.loads((EXAMPLE / "reference.json").read_text())
    scene["render"]["seed"] = 5000 + i
    if base == "heidi":
        scene["render"]["max_depth"] = 1
        scene["lights"] = [{"type": "point", "position": [0, 3.5, 0], "intensity": 0.0001}]
        scene["ambient"] = 0.6
    image = render(scene)
    if (i // len(names)) % 2:
        return f"hw4/{who}.exr", exr_bytes(image.astype(np.float16))
    return f"hw4/{who}.png", png_bytes(image)


def make_class(n: int) -> bytes:
    """A zip of `n` submissions made from the nine of the example, each copy a little different."""
    names = class_names()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for i in range(n):
            z.writestr(*submission_file(i, names[i % len(names)]))
    return buf.getvalue()


def exr_bytes(image) -> bytes:
    import OpenEXR

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "image.exr"
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with OpenEXR.File(header, {"RGB": image}) as f:
            f.write(str(path))
        return path.read_bytes()


def multipart(fields: dict[str, str], files: dict[str, tuple[str, bytes]]) -> tuple[bytes, str]:
    boundary = "bench-grading-" + os.urandom(8).hex()
    out = io.BytesIO()
    for name, value in fields.items():
        out.write(f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'.encode())
        out.write(value.encode() + b"\r\n")
    for name, (filename, data) in files.items():
        out.write(f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"; filename="{filename}"\r\n'
                  "Content-Type: application/zip\r\n\r\n".encode())  # fmt: skip
        out.write(data + b"\r\n")
    out.write(f"--{boundary}--\r\n".encode())
    return out.getvalue(), f"multipart/form-data; boundary={boundary}"


def tree_cpu(pid: int, waited: bool = False) -> dict[int, float]:
    """CPU seconds (user + system) of a process and each of its descendants alive now, by pid (Linux /proc);
    `waited`: each with its children that ended and were waited for (a worker host's work horses)."""
    tick = os.sysconf("SC_CLK_TCK")
    stats = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        ticks = sum(int(f) for f in fields[11 : 15 if waited else 13])
        stats[int(stat.parent.name)] = (int(fields[1]), ticks / tick)
    out, todo = {}, [pid]
    while todo:
        p = todo.pop()
        if p in stats:
            out[p] = stats[p][1]
            todo += [c for c, (parent, _) in stats.items() if parent == p]
    return out


def cpu_used(before: dict[int, float], after: dict[int, float], api: int) -> dict[int, float]:
    """CPU seconds of each of the server's processes between two looks, by pid."""
    return {p: t - before.get(p, 0.0) for p, t in after.items()}


def cpu_roles(used: dict[int, float], api: int, log: str) -> dict[str, float]:
    """The CPU seconds split by role: the API process, its render workers (their pids from the server's
    log: "started render worker k (pid P)"), and the rest (the grading processes, Python's resource tracker)."""
    workers = {int(m) for m in re.findall(r"started render worker \d+ \(pid (\d+)\)", log)}
    render = sum(t for p, t in used.items() if p in workers)
    return {"total": sum(used.values()), "api": used.get(api, 0.0), "workers": render,
            "grading": sum(used.values()) - used.get(api, 0.0) - render}  # fmt: skip


def grade(api: Api, zip_bytes: bytes) -> tuple[dict, dict]:
    """Upload the class and follow the run; (its final state, the timeline in seconds from the upload)."""
    body, ctype = multipart({"assignment": json.dumps(assignment())}, {"class": ("class.zip", zip_bytes)})
    t0 = time.perf_counter()
    api.conn.request("POST", "/api/grade/upload", body=body, headers={"content-type": ctype})
    r = api.conn.getresponse()
    data = r.read()
    if r.status != 202:
        raise RuntimeError(f"upload: {r.status} {data[:300]!r}")
    marks = {"accepted": time.perf_counter() - t0}
    run = json.loads(data)
    while True:
        state = api.json("GET", f"/api/grade/{run['id']}")
        now = time.perf_counter() - t0
        if state["renders_total"] is not None and "prepared" not in marks:
            marks["prepared"] = now
        if state["renders_total"] and state["renders_done"] >= state["renders_total"] and "rendered" not in marks:
            marks["rendered"] = now
        if state["status"] != "running":
            marks["done"] = now
            return state, marks
        time.sleep(0.05)


def split(data_dir: Path, log: str, run_id: str, workers: int) -> dict:
    """The run's time, split: from its rows, its jobs' rows, and the workers' log."""
    db = sqlite3.connect(data_dir / "jobs.sqlite3")
    ids = [r[0] for r in db.execute(
        "SELECT job_id FROM grading_items WHERE run_id = ?1 AND job_id IS NOT NULL"
        " UNION SELECT job_id FROM grading_renders WHERE run_id = ?1", (run_id,))]  # fmt: skip
    marks = ",".join("?" * len(ids))
    rows = db.execute(f"SELECT id, created_at, started_at, finished_at, name FROM jobs WHERE id IN ({marks})", ids)
    jobs = [dict(zip(("id", "created", "started", "finished", "name"), r, strict=True)) for r in rows]
    halves = db.execute("SELECT COALESCE(prepare_seconds, 0), COALESCE(metrics_seconds, 0) FROM grading_items"
                        " WHERE run_id = ?", (run_id,)).fetchall()  # fmt: skip
    prepare, metrics = [h[0] for h in halves], [h[1] for h in halves]
    created = db.execute("SELECT created_at, finished_at FROM grading_runs WHERE id = ?", (run_id,)).fetchone()
    db.close()
    inside = {m[1]: float(m[2]) for m in re.finditer(r"job (\S+): done, ([0-9.]+) s", log)}
    first_start, last_end = min(j["started"] for j in jobs), max(j["finished"] for j in jobs)
    busy = sum(j["finished"] - j["started"] for j in jobs)
    students = [j for j in jobs if not j["name"].startswith(("grading: reference", "grading: baseline"))]
    return {
        "jobs": len(jobs), "students_rendered": len(students),
        "render_inside": sum(inside.get(j["id"], 0.0) for j in jobs),
        "render_inside_reference": sum(inside.get(j["id"], 0.0) for j in jobs if j not in students),
        "in_worker": busy, "render_phase": last_end - first_start,
        "idle": workers * (last_end - first_start) - busy,
        "first_render_start": first_start - created[0], "after_last_render": created[1] - last_end,
        "prepare": sum(prepare), "metrics": sum(metrics), "run": created[1] - created[0],
    }  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="bench.grading", description=__doc__.splitlines()[0])
    p.add_argument("--students", type=int, default=300)
    p.add_argument("--workers", type=int, default=2, help="render worker processes of the server")
    p.add_argument("--runs", type=int, default=1, help="times the class is graded (a fresh server each)")
    p.add_argument("--keep", type=Path, help="keep the data directories and logs here")
    args = p.parse_args(argv)
    from tracer.rendering.progressive import load_kernels

    load_kernels()
    t = time.perf_counter()
    zip_bytes = make_class(args.students)
    print(f"class: {args.students} submissions, a {len(zip_bytes) / 1e6:.2f} MB zip "
          f"(made in {time.perf_counter() - t:.1f} s)")  # fmt: skip
    print(f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"{args.workers} render worker(s), grading processes: one per core")  # fmt: skip
    for k in range(args.runs):
        if args.keep is not None:
            args.keep.mkdir(parents=True, exist_ok=True)
        root = Path(tempfile.mkdtemp(prefix="bench-grading-", dir=args.keep))
        proc, port = start_server(root / "data", args.workers)
        api = Api(port)
        try:
            warm = make_one()
            state, _ = grade(api, warm)
            assert state["status"] == "done", state
            before = tree_cpu(proc.pid)
            state, marks = grade(api, zip_bytes)
            marks["cpu"] = cpu_used(before, tree_cpu(proc.pid), proc.pid)
            assert state["status"] == "done", state
        finally:
            api.close()
            proc.terminate()
            proc.wait(timeout=60)
        log = (root / "server.log").read_text(errors="replace")
        s = split(root / "data", log, state["id"], args.workers)
        marks["cpu"] = cpu_roles(marks["cpu"], proc.pid, log)
        report(k + 1, state, marks, s, args.workers)
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)


def make_one() -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.write(CLASS / "alice.json", "alice.json")
    return buf.getvalue()


def report(run: int, state: dict, marks: dict, s: dict, workers: int) -> None:
    by = state["summary"]["statistics"]["by_status"]
    wall = marks["done"]
    print(f"\nrun {run}: {len(state['students'])} students ({by}), {s['jobs']} render jobs: "
          f"{wall:.1f} s from the upload to the last report")  # fmt: skip
    print(f"  upload to 202 (body, unzip, rows): {marks['accepted']:.2f} s; every student prepared at "
          f"{marks.get('prepared', 0):.2f} s; the first render started {s['first_render_start']:.2f} s "
          "after the run did")  # fmt: skip
    print(f"  renders: {s['render_phase']:.2f} s from the first start to the last end on {workers} worker(s); "
          f"inside the renderer {s['render_inside']:.2f} s of worker time (the class's reference renders "
          f"{s['render_inside_reference']:.2f} s), in the workers {s['in_worker']:.2f} s "
          f"({1000 * (s['in_worker'] - s['render_inside']) / s['jobs']:.1f} ms a job around the renderer), "
          f"idle {s['idle']:.2f} s ({1000 * s['idle'] / s['jobs']:.1f} ms a job)")  # fmt: skip
    print(f"  grading processes: prepare {s['prepare']:.2f} s, metrics {s['metrics']:.2f} s of process time "
          f"({1000 * s['metrics'] / len(state['students']):.1f} ms a student); after the last render "
          f"{s['after_last_render']:.2f} s to the summary")  # fmt: skip
    cpu = marks["cpu"]
    print(f"  CPU of the server's processes: {cpu['total']:.1f} s: the render workers {cpu['workers']:.1f} s, "
          f"the grading processes {cpu['grading']:.1f} s, the API process {cpu['api']:.2f} s (HTTP, the rows, "
          "polling the jobs)")  # fmt: skip
    print(f"  the renderer's share of the CPU, at most: {cpu['workers']:.1f} s / {cpu['total']:.1f} s = "
          f"{100 * cpu['workers'] / cpu['total']:.0f} % (the render workers' CPU, the work around each render "
          "included)")  # fmt: skip
    lower = s["render_inside"] / workers
    print(f"  the renderer's share of the wall time: {lower:.2f} s / {wall:.1f} s = {100 * lower / wall:.0f} %")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
