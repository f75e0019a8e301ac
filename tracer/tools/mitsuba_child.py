"""One Mitsuba 3 render as a whole process, for `python -m tracer bench --mitsuba` (tracer/tools/bench_mitsuba.py).

    PYTHON tracer/tools/mitsuba_child.py SPEC.json VARIANT SPP OUT.npy [--seed S] [--threads T]

Run by its path with any interpreter that has `mitsuba` (it imports nothing of the tracer, so Mitsuba may
live in a virtual environment of its own). SPEC.json is the scene as `bench_mitsuba.write_spec` wrote it:
Mitsuba's scene dictionary, with the sensor's transform as look-at parameters. Writes the linear RGB
image (float32, H x W x 3) to OUT.npy and prints one JSON line: the seconds of the import, the scene's
load and the render (its JIT compilation included, as a user of the variant would wait for it).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import time


def llvm_path() -> None:
    """Point Dr.Jit at a system libLLVM (Debian's libllvm) when none is set."""
    if not os.environ.get("DRJIT_LIBLLVM_PATH"):
        found = sorted(glob.glob("/usr/lib/*/libLLVM-1[5-9]*.so*") or glob.glob("/usr/lib/*/libLLVM.so*"), reverse=True)
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found[0]


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("spec")
    p.add_argument("variant")
    p.add_argument("spp", type=int)
    p.add_argument("out")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=0, help="0: Mitsuba's default (one per core)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    if args.variant.startswith("llvm"):
        llvm_path()
    import drjit as dr  # pyright: ignore[reportMissingImports]  (in Mitsuba's interpreter, not in .venv)
    import mitsuba as mi  # pyright: ignore[reportMissingImports]  (in Mitsuba's interpreter, not in .venv)
    import numpy as np

    mi.set_variant(args.variant)
    if args.threads:
        dr.set_thread_count(args.threads)
    t1 = time.perf_counter()
    spec = json.loads(open(args.spec).read())
    look = spec["sensor"].pop("look_at")
    spec["sensor"]["to_world"] = mi.ScalarTransform4f().look_at(**look)
    spec["sensor"]["sampler"]["sample_count"] = args.spp
    scene = mi.load_dict(spec)
    t2 = time.perf_counter()
    img = np.asarray(mi.render(scene, spp=args.spp, seed=args.seed))
    t3 = time.perf_counter()
    np.save(args.out, img[..., :3].astype(np.float32))
    print(json.dumps({"import_s": t1 - t0, "load_s": t2 - t1, "render_s": t3 - t2}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
