"""A grading run's work, as functions of plain data (JSON text, dicts, file paths, numbers) that run in
any process and return plain data.

The service runs them in a pool of worker processes beside the API (server/grading/runs.py), so no
submission is parsed and no image compared in the API process; a job queue could run them as jobs
of their own kind, as they take nothing but data and files. The grading logic is the library's
(`Grader.prepare`, `finish_report`): the same reports as grading in process, bit for bit.

- `prepare_submission`: validity, requirements, and the render the image tests need (a `Prepared`
  as JSON), the first half of a student's grade;
- `measure_baseline`: the noise baseline's metrics for one (sampler, spp, light samples) and one way
  of storing images, shared by the students rendered and stored that way;
- `grade_metrics`: one student's image tests (FLIP, SSIM, PSNR and the per-pixel z test) against the
  reference and the baseline, and their report and pictures written to their folder.

Images are passed as paths to EXR files (our renders: `image.exr`; the reference's variance: the RGB
of its `aovs.exr`) or to the student's own file; the reference mean and variance are read once per
process (the files a run keeps never change).
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np

from tracer.grading.batch import summary_row, write_report
from tracer.grading.grader import Grader
from tracer.grading.imagetests import ReferenceImages, baseline_metrics, finish_report
from tracer.grading.metrics import Encoding
from tracer.grading.prepared import Prepared
from tracer.grading.renders import Rendered
from tracer.grading.spec import load_assignment
from tracer.grading.submission import Submission, decode_image


@functools.lru_cache(maxsize=4)
def grader(assignment: str) -> Grader:
    """The grader of an assignment (its JSON text, the reference scene inline), made once per process."""
    spec, _ = load_assignment(assignment)
    return Grader(spec, None)


@functools.lru_cache(maxsize=8)
def _exr(path: str) -> np.ndarray:
    from tracer.rendering.film import read_exr

    return read_exr(Path(path))


def reference_images(assignment: str, reference: dict) -> ReferenceImages | None:
    """{"mean": path, "variance": path, "spp": n} or {"error": why} -> the reference to compare with."""
    g = grader(assignment)
    if g.reference is None:
        return None
    if reference.get("error") or not reference.get("mean"):
        return ReferenceImages(g.reference.exposure, error=reference.get("error") or "no reference render")
    return ReferenceImages(
        g.reference.exposure, _exr(reference["mean"]), _exr(reference["variance"]), int(reference["spp"])
    )


def probe_image(assignment: str, mean: str, path: str, kind: str) -> dict:
    """The probes of a student's image (a check: nothing kept) against the reference mean (an EXR's path):
    {"probes": [...]} or {"error": why} (a size that is not the reference's, a file that is not an image)."""
    from tracer.grading import metrics
    from tracer.grading.probes import find, flip_error
    from tracer.grading.submission import decode_image

    g = grader(assignment)
    exposure = g.reference.exposure if g.reference is not None else 0.0
    try:
        image, encoding = decode_image(Path(path).read_bytes(), kind)
        reference = _exr(mean)
        metrics.same_size(reference, image)
    except metrics.GradingError as e:
        return {"error": str(e)}
    shown = metrics.display(image, exposure) if encoding.linear else image
    listed = [p.model_dump() for p in g.assignment.reference.probes] if g.assignment.reference else []
    return {"probes": [p.to_json() for p in find(flip_error(metrics.display(reference, exposure), shown), listed)]}


def rendered(render: dict | None) -> Rendered | None:
    """{"image": path, "spp": n, "seconds": s} or {"error": why} (None: no render) -> a Rendered."""
    from tracer.rendering.film import read_exr

    if render is None:
        return None
    if render.get("error"):
        return Rendered(error=render["error"])
    return Rendered(read_exr(Path(render["image"])), None, int(render["spp"]), float(render.get("seconds", 0.0)))


def prepare_submission(assignment: str, student: str, kind: str, path: str, filename: str = "") -> dict:
    """A submission (its file at `path`: a scene's JSON, or a PNG or EXR) -> {"prepared": Prepared JSON,
    "seconds": time taken}."""
    start = time.perf_counter()
    sub = Submission(student, Path(path).read_bytes(), kind, filename)
    p = grader(assignment).prepare(sub)
    return {"prepared": p.to_json(), "seconds": time.perf_counter() - start}


def measure_baseline(assignment: str, reference: dict, baseline: dict, key: list, encoding: list) -> dict:
    """The noise baseline's metrics (flip, ssim, psnr, rejected; or {"error"}) for submissions rendered as
    `key` ([sampler, spp, light_samples]) and stored as `encoding` ([format, bits]); `baseline` is its
    render as `rendered` takes it."""
    g = grader(assignment)
    ref = reference_images(assignment, reference)
    assert ref is not None, "a baseline is measured for an assignment with a reference scene alone"
    return baseline_metrics(g.assignment, ref, rendered(baseline), tuple(key), Encoding(*encoding))


def grade_metrics(
    assignment: str,
    prepared: dict,
    out: str,
    *,
    submission: str | None = None,
    render: dict | None = None,
    reference: dict | None = None,
    baseline: dict | None = None,
) -> dict:
    """One student's grade, finished: their image tests and report.

    assignment: its JSON text; prepared: what `prepare_submission` gave; out: their folder of results
    (results.json, report.json, the pictures); submission: the path of their file (their own image is
    read from it); render: their render as `rendered` takes it (scenes); reference: as
    `reference_images` takes it; baseline: `measure_baseline`'s metrics for their key and encoding.
    -> {"report": report.json's content, "row": their summary row, "score", "max_score" (exact), "seconds"}."""
    start = time.perf_counter()
    g = grader(assignment)
    p = Prepared.from_json(prepared)
    if p.report.kind == "image" and not p.report.errors and submission is not None:
        p.image, _ = decode_image(Path(submission).read_bytes(), p.sub.kind)
    ref = reference_images(assignment, reference or {}) if g.reference is not None else None
    report = finish_report(
        g.assignment, p, rendered(render), ref, lambda: baseline if baseline is not None else {"error": "no baseline"}
    )
    write_report(Path(out), report)
    return {
        "report": report.to_json(), "row": summary_row(report), "score": report.score,
        "max_score": report.max_score, "seconds": time.perf_counter() - start,
    }  # fmt: skip
