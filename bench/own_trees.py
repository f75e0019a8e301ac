"""Benchmark of own tracers' tree logs (docs/own-tracer.md, #38): how long the service takes to compare a log
of 8 trees with the reference's.

    python -m bench.own_trees [--rounds 20] [--trees 8] [--json]

It starts `python -m server` on 127.0.0.1 (one worker, a fresh data directory, an instructor token), publishes
an assignment whose reference is tests/owntracer/zoo_scene.json, enrols one student and hands in the zoo
tracer's right image. Then it measures POST /api/assignments/{aid}/submissions/{sid}/trees with a log of 8 trees
(the zoo tracer's own at the 8 pixels whose trees are largest: the glass, the mirror):
1. cold: the first POST, whose reference trees are traced by the worker (8 ray-tree jobs of the interactive
   lane);
2. warm: the same POST again, `--rounds` times (the reference trees kept per assignment version): the median and
   the slowest;
3. the comparison alone, in this process (Explainer.compare with the trees handed over): the part of the warm
   time that is Python.
"""

from __future__ import annotations

import argparse
import base64
import io
import json
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from bench.service import Api, start_server

ROOT = Path(__file__).resolve().parent.parent
TOKEN = "bench-own-trees-instructor-token-0123456789"


def zoo():
    """The zoo tracer of the tests (tests/owntracer/zoo_tracer.py): the scene, its right trees and picture."""
    from tests.owntracer.zoo_tracer import zoo_render, zoo_scene

    _, trees, picture = zoo_render(None)
    return zoo_scene(), trees, picture


def png(picture) -> str:
    import numpy as np
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.round(np.asarray(picture) * 255).astype("uint8") if picture.dtype != "uint8" else picture).save(
        buf, "PNG"
    )
    return base64.b64encode(buf.getvalue()).decode()


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=20, help="warm POSTs (default 20)")
    p.add_argument("--trees", type=int, default=8, help="trees in the log (default 8)")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)

    scene, trees, picture = zoo()
    pixels = sorted(trees, key=lambda px: (-len(trees[px]["nodes"]), px))[: args.trees]  # the largest trees
    log = json.dumps({"trees": [trees[px] for px in pixels]}).encode()
    root = Path(tempfile.mkdtemp(prefix="bench-own-trees-"))
    proc = None
    try:
        data = root / "data"
        proc, port = start_server(data, 1, env={"TRACER_INSTRUCTOR_TOKEN": TOKEN}, token=TOKEN)
        staff = Api(port, TOKEN)
        spec = {"version": 1, "name": "bench", "reference": {"scene": scene, "spp": 16, "flip": {"points": 1}}}
        aid = staff.json("POST", "/api/assignments", {"spec": spec, "deadline": "2099-01-01T00:00:00+00:00"})["id"]
        status, body = staff.call("POST", f"/api/assignments/{aid}/roster", b"id,name,email\ns1,Student,\n")
        token = json.loads(body)["students"][0]["token"]
        student = Api(port, token)
        sid = student.json("POST", f"/api/assignments/{aid}/submissions", {"image": png(picture), "format": "png"})[
            "id"
        ]
        deadline = time.monotonic() + 600
        while student.json("GET", f"/api/assignments/{aid}/submissions/{sid}")["status"] not in ("graded", "failed"):
            if time.monotonic() > deadline:
                raise RuntimeError("the submission was not graded in 10 minutes")
            time.sleep(0.2)
        url = f"/api/assignments/{aid}/submissions/{sid}/trees"
        t0 = time.perf_counter()
        status, body = student.call("POST", url, log)
        cold = time.perf_counter() - t0
        if status != 200:
            raise RuntimeError(f"POST {url}: {status} {body[:300]!r}")
        answers = json.loads(body)["trees"]
        warm = []
        for _ in range(args.rounds):
            t0 = time.perf_counter()
            status, body = student.call("POST", url, log)
            warm.append(time.perf_counter() - t0)
            if status != 200:
                raise RuntimeError(f"POST {url}: {status} {body[:300]!r}")
        from tracer.grading.explain import Explainer

        ex = Explainer(scene, device=None)
        handed = {tuple(a["pixel"]): a["reference"] for a in answers}
        alone = []
        for _ in range(args.rounds):
            t0 = time.perf_counter()
            ex.compare(log, None, handed)
            alone.append(time.perf_counter() - t0)
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(timeout=60)
        shutil.rmtree(root, ignore_errors=True)
    result = {
        "trees": len(pixels),
        "nodes": sum(len(trees[px]["nodes"]) for px in pixels),
        "matching": sum(a["matches"] for a in answers),
        "cold_s": round(cold, 3),
        "warm_median_s": round(statistics.median(warm), 4),
        "warm_max_s": round(max(warm), 4),
        "compare_alone_median_s": round(statistics.median(alone), 4),
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"a log of {result['trees']} trees ({result['nodes']} nodes; {result['matching']} match):")
        print(f"  cold (the reference's trees traced by the worker): {result['cold_s']:.3f} s")
        print(
            f"  warm, {args.rounds} POSTs: median {result['warm_median_s']:.4f} s, slowest {result['warm_max_s']:.4f} s"
        )
        print(f"  the comparison alone (Python, this process): median {result['compare_alone_median_s']:.4f} s")
    return result


if __name__ == "__main__":
    main()
