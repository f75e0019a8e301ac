"""Command line: render, raytree, validate, bench, grade, docs.

python -m tracer render SCENE.json -o OUT.png [--spp N] [--width W] [--height H] [--seed S]
                        [--integrator NAME] [--max-depth D] [--threads T] [--exr OUT.exr]
                        [--device cpu|cuda:0]
python -m tracer raytree SCENE.json X Y [--sample K] [--text | --pretty]
python -m tracer validate SCENE.json [--assets DIR]
python -m tracer bench [--quick] [--mitsuba [--mitsuba-python PY] [--rounds N]] [--only SECTIONS]
python -m tracer grade ASSIGNMENT.json SUBMISSION [-o OUT] [--workers N] [--json]
    SUBMISSION: a scene (.json), a student's image (.png/.exr), or a class (a folder or a .zip)
python -m tracer explain ASSIGNMENT_OR_SCENE --image MINE.png [--trees MINE.json] [--json]
    a student's own tracer: the probe pixels of their image, and each logged ray tree against the reference's
python -m tracer docs [--check]     the field tables of docs/scene-format.md, from tracer/scene/
"""

from __future__ import annotations

import gc

if __name__ == "__main__":  # python -m tracer: no garbage collection while starting (see `main`)
    gc.disable()

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from tracer.scene import ASSET_DIR, SceneError, load_scene, validate_scene  # noqa: E402
from tracer.tools.jsonpos import locate, positions  # noqa: E402


def _read_json(path: str) -> dict:
    """The scene file as a dict; JSON syntax errors become SceneError with line and column."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise SceneError([{"path": "", "message": f"cannot read {path}: {exc.strerror}"}]) from exc
    return parse_json(text)


def parse_json(text: str):
    """The JSON text's value; a syntax error becomes a SceneError at its line and column (`at`, for the
    file's FILE:LINE:COL prefix)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        message = f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}"
        raise SceneError([{"path": "", "message": message, "at": (exc.lineno, exc.colno)}]) from exc


def _overrides(data: dict, args) -> dict:
    """Apply command-line settings to the raw scene, so validation and limits see them."""
    if not isinstance(data, dict):
        return data

    def put(section, key, value):
        if value is not None:
            if not isinstance(data.get(section), dict):
                data[section] = {}
            data[section][key] = value

    put("sampler", "spp", getattr(args, "spp", None))
    put("film", "width", getattr(args, "width", None))
    put("film", "height", getattr(args, "height", None))
    put("render", "seed", getattr(args, "seed", None))
    put("render", "integrator", getattr(args, "integrator", None))
    put("render", "max_depth", getattr(args, "max_depth", None))
    return data


def _print_problems(items: list[dict], kind: str = "error", scene: str | None = None, file=None) -> None:
    """A scene's errors (or warnings) one a line, `FILE:LINE:COL: error: PATH: MESSAGE`, each at its JSON path's
    place in the scene file's text (tracer/tools/jsonpos.py: a missing field at its object), as compilers write them
    and as the page's editor marks them; without a file (or one that is not JSON) `error: PATH: MESSAGE`. `file`:
    standard error as it is when called (None)."""
    file = sys.stderr if file is None else file
    text = found = None
    if scene is not None and items:
        try:
            text = Path(scene).read_text()
        except (OSError, UnicodeDecodeError):
            text = None
        found = positions(text) if text is not None else None
    for e in items:
        at = e.get("at")  # a syntax error brings its own
        if not at and found and text is not None:
            at = locate(text, e["path"], found)
        where = f"{scene}:{at[0]}:{at[1]}: " if at and scene is not None else ""
        print(f"{where}{kind}: {e['path'] or '(scene)'}: {e['message']}", file=file)


def cmd_render(args) -> int:
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.film import aov_layers, write_exr, write_png
    from tracer.rendering.progressive import load_kernels, render

    scene, warnings = load_scene(_overrides(_read_json(args.scene), args), assets=args.assets)
    _print_problems(warnings, "warning", args.scene)
    # render() solves a radiosity scene, with progress
    cs = compile_scene(scene, asset_dir=Path(args.assets), device=args.device)
    load_kernels(args.device, [cs.data.integrator])
    started()
    bars: dict = {}
    show = sys.stderr.isatty() and not args.quiet
    last = 0

    def progress(p) -> None:
        nonlocal last
        if not show:
            return
        from tqdm import tqdm

        if p.phase == "radiosity":  # the radiosity solve comes first: its own bar, in percent
            bar = bars.get("radiosity")
            if bar is None:
                bar = bars["radiosity"] = tqdm(total=100, unit="%", desc="radiosity solve", file=sys.stderr)
            bar.set_postfix_str(f"{p.solve['shots']} shots, {100 * p.solve['unshot']:.2f}% unshot", refresh=False)
            bar.update(int(100 * p.solve["fraction"]) - bar.n)
            return
        bar = bars.get("render")
        if bar is None:
            if "radiosity" in bars:
                bars["radiosity"].update(100 - bars["radiosity"].n)
                bars["radiosity"].close()
            desc = Path(args.scene).name
            bar = bars["render"] = tqdm(total=p.samples_total, unit="spl", unit_scale=True, desc=desc, file=sys.stderr)
        bar.update(p.samples_done - last)
        last = p.samples_done

    result = render(cs, threads=args.threads, progress=progress, device=args.device)
    for bar in bars.values():
        bar.close()
    write_png(args.output, result.image, scene.film.exposure)
    if args.exr:
        write_exr(args.exr, result.image, aov_layers(result.aovs) if args.aovs else None)
    if scene.sampler.type == "adaptive":
        per_pixel = result.aovs["rays"].mean()
        sampling = f"adaptive to level {scene.sampler.max_level} ({per_pixel:.1f} rays/pixel)"
    else:
        sampling = f"{result.spp} spp"
    on = "" if args.device == "cpu" else f" on {args.device}"
    print(f"{args.output}: {scene.film.width}x{scene.film.height}, {sampling}{on}, {result.stats_line()}")
    return 0


def cmd_raytree(args) -> int:
    from tracer.rendering.raytree import ray_tree

    scene, warnings = load_scene(_read_json(args.scene), assets=args.assets)
    from tracer.kernels.compile import compile_scene

    tree = ray_tree(compile_scene(scene, asset_dir=Path(args.assets)), args.x, args.y, args.sample)
    if args.text:
        from tracer.rendering.raytree import tree_text

        sys.stdout.write(tree_text(tree))
        return 0
    json.dump(tree, sys.stdout, indent=1 if args.pretty else None)
    print()
    return 0


def cmd_validate(args) -> int:
    report = validate_scene(_read_json(args.scene), assets=args.assets)
    _print_problems(report["warnings"], "warning", args.scene)
    if not report["valid"]:
        _print_problems(report["errors"], "error", args.scene)
        return 1
    print(f"{args.scene}: valid")
    return 0


def cmd_bench(args) -> int:
    from tracer.tools.bench import main as bench_main

    started()
    return bench_main(args)


def _percent_text(p: float) -> str:
    """46.15 -> "46.2%", 100.0 -> "100%"."""
    return f"{p:.1f}".removesuffix(".0") + "%"


def cmd_docs(args) -> int:
    from tracer.tools.scene_docs import main as docs_main

    return docs_main(check=args.check, path=Path(args.file))


def cmd_grade(args) -> int:
    from tracer.grading import (
        AssignmentError,
        Grader,
        GradingError,
        Submission,
        collect,
        load_assignment,
        student_for_file,
        write_all,
    )

    try:
        assignment, base = load_assignment(Path(args.assignment))
        grader = Grader(assignment, base, None)
    except AssignmentError as exc:
        for e in exc.errors:
            print(f"error: assignment: {e['path'] or '(assignment)'}: {e['message']}", file=sys.stderr)
        return 1
    path = Path(args.submission)
    out = Path(args.output) if args.output else default_output(path)
    batch = path.is_dir() or path.suffix.lower() == ".zip"
    try:
        if batch:
            subs = collect(path)
        else:
            kind = {".png": "png", ".exr": "exr"}.get(path.suffix.lower(), "scene")
            subs = [Submission(args.student or student_for_file(path.name), path.read_bytes(), kind, path.name)]
    except (GradingError, OSError) as exc:
        print(f"error: {path}: {getattr(exc, 'strerror', None) or exc}", file=sys.stderr)
        return 1
    if not subs:
        print(f"error: {path}: no submissions (.json, .png or .exr files)", file=sys.stderr)
        return 1
    started()
    if batch:  # worker processes of our own, a time limit per render
        from tracer.grading.local import LocalRenderer

        shown = [-1]

        def progress(done: int, total: int) -> None:
            if done != shown[0]:
                shown[0] = done
                print(f"renders done: {done}/{total}", file=sys.stderr, flush=True)

        log_path = out / ".queue" / WORKER_LOG
        print(f"the render workers log to {log_path}", file=sys.stderr, flush=True)
        with LocalRenderer(args.workers, log_path=log_path, on_progress=progress) as renderer:
            grader.renderer = renderer
            reports = grader.grade(subs)
    else:
        from tracer.grading import InlineRenderer

        grader.renderer = InlineRenderer(args.threads)
        reports = grader.grade(subs)
    table = write_all(out, reports)
    if args.json:
        json.dump(table if batch else reports[0].to_json(), sys.stdout, indent=1)
        print()
        return 0
    for r in reports:
        share = f" = {_percent_text(100 * r.score / r.max_score)}" if r.max_score > 0 else ""
        print(f"{r.student}: {r.score:g} / {r.max_score:g}{share} ({r.status})")
        if not batch:
            for t in r.tests:
                print(f"  {'PASS' if t.passed else 'FAIL'} {t.name} ({t.score:g}/{t.max_score:g}): "
                      + t.output.replace("\n", "\n      "))  # fmt: skip
    stats = table["statistics"]
    if batch:
        shares = [100 * r.score / r.max_score for r in reports if r.max_score > 0]
        mean = _percent_text(sum(shares) / len(shares)) if shares else "-"
        print(f"{stats['students']} students, mean {mean} of the points; summary in {out / 'summary.csv'}")
    else:
        print(f"report and pictures in {out / reports[0].student}/")
    return 0


def cmd_explain(args) -> int:
    from tracer.grading import AssignmentError, GradingError, owntracer
    from tracer.grading.submission import decode_image

    image_path = Path(args.image)
    kind = {".png": "png", ".exr": "exr"}.get(image_path.suffix.lower(), "png")
    try:
        shown, encoding = decode_image(image_path.read_bytes(), kind)
        trees = Path(args.trees).read_bytes() if args.trees else None
    except (GradingError, OSError) as exc:
        print(f"error: {getattr(exc, 'filename', None) or image_path}: {getattr(exc, 'strerror', None) or exc}",
              file=sys.stderr)  # fmt: skip
        return 1
    try:
        started()
        ref = owntracer.load_reference(Path(args.source), args.threads)
        if encoding.linear:
            from tracer.grading import metrics

            shown = metrics.display(shown, float(ref.scene.get("film", {}).get("exposure", 0.0)))
        result = owntracer.explain(ref, shown, trees)
    except AssignmentError as exc:
        for e in exc.errors:
            print(f"error: assignment: {e['path'] or '(assignment)'}: {e['message']}", file=sys.stderr)
        return 1
    except GradingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except SceneError as exc:
        _print_problems(exc.errors, "error", args.trees if trees is not None else args.source)
        return 1
    if args.json:
        json.dump(result, sys.stdout)
        print()
    else:
        sys.stdout.write(owntracer.text(result))
    return 0 if all(a["matches"] for a in result["trees"]) else 2


WORKER_LOG = "workers.log"  # a class's render workers log here, under OUT/.queue/


def default_output(submission: Path) -> Path:
    """`grade`'s folder without -o: beside what is graded, named after it (hw4/ and hw4.zip -> hw4-grades/),
    never a folder of whatever directory the command runs in (a checkout's, say)."""
    if submission.name in ("", ".", ".."):  # grading the folder one is in: its name
        submission = submission.resolve()
    stem = submission.name if submission.is_dir() else submission.stem
    return submission.parent / f"{stem}-grades"


def _device(name: str) -> str:
    """--device: Warp's name of the device, or a usage error naming the devices there are."""
    from tracer.kernels.parallel import device_arg

    return device_arg(name)


ASSETS_HELP = "folder that mesh and image files are read from (default: scenes/assets)"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="tracer", description="Educational ray tracer on NVIDIA Warp.")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a scene to PNG (and EXR)")
    r.add_argument("scene")
    r.add_argument("-o", "--output", required=True, help="PNG file to write")
    r.add_argument("--spp", type=int, help="samples per pixel (grid/jittered: a perfect square)")
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--seed", type=int)
    r.add_argument("--integrator")
    r.add_argument("--max-depth", type=int, dest="max_depth")
    r.add_argument("--threads", type=int, help="render threads (default: one per core)")
    r.add_argument(
        "--device",
        default="cpu",
        type=_device,
        help="Warp device: cpu (default) or a GPU such as cuda:0 (whole images per launch; see docs/scale.md)",
    )
    r.add_argument("--exr", help="also write the linear float image as OpenEXR")
    r.add_argument(
        "--aovs",
        action="store_true",
        help="with --exr: add layers depth.Z, normal, albedo, rays.Y (rays per pixel) and variance",
    )
    r.add_argument("--assets", default=str(ASSET_DIR), help=ASSETS_HELP)
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=cmd_render)

    t = sub.add_parser("raytree", help="print the ray tree of one pixel sample as JSON (or as text: --text)")
    t.add_argument("scene")
    t.add_argument("x", type=int, help="column from the left")
    t.add_argument("y", type=int, help="row from the top")
    t.add_argument("--sample", type=int, default=0)
    t.add_argument("--pretty", action="store_true", help="indent the JSON")
    t.add_argument(
        "--text",
        action="store_true",
        help="indented lines instead of JSON, one ray per line: its kind, what it hit, its weight, what it "
        "carries back and why it ended",
    )
    t.add_argument("--assets", default=str(ASSET_DIR), help=ASSETS_HELP)
    t.set_defaults(func=cmd_raytree)

    v = sub.add_parser(
        "validate", help="check a scene and its asset files; errors with JSON paths, exit status 1 when invalid"
    )
    v.add_argument("scene")
    v.add_argument("--assets", default=str(ASSET_DIR), help=ASSETS_HELP)
    v.set_defaults(func=cmd_validate)

    b = sub.add_parser("bench", help="measure Msamples/s and Mrays/s per ray kind on the example scenes")
    b.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    b.add_argument("--threads", type=int, default=None)
    b.add_argument("--out", help="also write the results as JSON to this file")
    b.add_argument(
        "--mitsuba",
        action="store_true",
        help="also the path-traced Cornell box against Mitsuba 3 as whole processes, alternating (pip install "
        "mitsuba; llvm_ad_rgb needs a libLLVM, Debian's libllvm19; its LLVM 15 fails on AVX-512 here)",
    )
    b.add_argument("--mitsuba-python", help="the Python that has mitsuba (default: this one)")
    b.add_argument("--rounds", type=int, default=3, help="--mitsuba: alternating rounds, medians (default 3)")
    b.add_argument("--baseline", help="--mitsuba: also time the tracer of this checkout (another commit's), alike")
    b.add_argument("--only", help="some of the sections, comma-separated: scenes, cornell, radiosity, scaling")
    b.set_defaults(func=cmd_bench)

    g = sub.add_parser("grade", help="grade a scene, a student's image or a class against an assignment")
    g.add_argument("assignment", help="the assignment spec (JSON; docs/grading.md)")
    g.add_argument("submission", help="a scene (.json), an image (.png, .exr), or a class: a folder or a .zip")
    g.add_argument(
        "-o",
        "--output",
        help="folder for the reports (default: beside the submission, named after it: hw4/ or hw4.zip -> "
        "hw4-grades/, bob.json -> bob-grades/)",
    )
    g.add_argument("--student", help="the student's name for one submission (default: the file name)")
    g.add_argument("--workers", type=int, default=2, help="a class: render worker processes (default 2)")
    g.add_argument("--threads", type=int, default=None, help="one submission: render threads")
    g.add_argument("--json", action="store_true", help="print the report (a class: the summary) as JSON")
    g.set_defaults(func=cmd_grade)

    e = sub.add_parser(
        "explain",
        help="your own tracer: the probe pixels of your image against the reference and, with a tree log, where "
        "your ray trees first differ from the reference's (docs/own-tracer.md)",
    )
    e.add_argument("source", help="the assignment (JSON with a reference) or the reference scene")
    e.add_argument("--image", required=True, help="your tracer's image of it (.png, or .exr)")
    e.add_argument("--trees", help="your tree log (JSON) of the probe pixels")
    e.add_argument("--threads", type=int, default=None, help="threads of the reference's render")
    e.add_argument("--json", action="store_true", help="print the probes and the answers as JSON")
    e.set_defaults(func=cmd_explain)

    from tracer.tools.scene_docs import DOC

    d = sub.add_parser("docs", help="write the field tables of the scene format reference from the models")
    d.add_argument("--check", action="store_true", help="only say whether they are up to date (exit 1 if not)")
    d.add_argument("--file", default=str(DOC), help="the reference (default: docs/scene-format.md)")
    d.set_defaults(func=cmd_docs)
    return p


_PAUSED = [False]  # the garbage collector is off while this process starts


def started() -> None:
    """A command has imported and loaded what it needs: the garbage collector goes back on, leaving out
    every object start-up made (gc.freeze). Start-up allocates hundreds of thousands of objects that live
    as long as the process (Warp's builtins and functions, the scene models), and every full collection
    while they are made walks them all again: 0.1 s of a tiny render's 0.7 (BENCHMARKS.md, #17). A short
    command (validate, raytree, docs) ends with it still off."""
    if _PAUSED[0]:
        _PAUSED[0] = False
        gc.freeze()
        gc.enable()


def main(argv: list[str] | None = None) -> int:
    if argv is None:  # this process's own command line (python -m tracer, or the `tracer` script)
        gc.disable()
        _PAUSED[0] = True
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except SceneError as exc:
        _print_problems(exc.errors, "error", getattr(args, "scene", None))
        return 1


if __name__ == "__main__":
    sys.exit(main())
