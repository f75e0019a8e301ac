"""The image tests, as plain functions: a submission's image (its render, or its own file) against the
reference scene's mean by FLIP, SSIM, PSNR and a per-pixel z test.

Fair to Monte Carlo noise: each image test's threshold is relative to a *noise baseline*, the
reference scene rendered exactly as the submission was (same spp, sampler and size) with another
seed. A correct scene at 4 spp is as noisy as the baseline and passes; a wrong one does not.

Grader.finish and the service's worker processes (tracer/grading/tasks.py) both grade through these:
they take the reference, the submission's image and the baseline's metrics as plain data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracer.grading import metrics
from tracer.grading.prepared import Prepared
from tracer.grading.renders import Rendered
from tracer.grading.report import Report, TestResult
from tracer.grading.spec import Assignment

TEST_NAMES = {  # the image tests as students see them
    "flip": "FLIP against the reference", "ssim": "SSIM against the reference",
    "psnr": "PSNR against the reference", "pixels": "pixels match the reference",
}  # fmt: skip


@dataclass
class ReferenceImages:
    """What every comparison is made against: the reference scene's mean and per-sample variance."""

    exposure: float  # the reference scene's film.exposure (the display of every image)
    mean: np.ndarray | None = None  # (H, W, 3) linear radiance
    variance: np.ndarray | None = None  # (H, W, 3) per-sample variance of the mean's samples
    spp: int = 0  # samples of the mean
    error: str | None = None  # why there is no mean (its render failed)


def measure(ref: ReferenceImages, image: np.ndarray, n: int, encoding: metrics.Encoding, alpha: float) -> dict:
    """Metrics of an image against the reference mean, in the units the image holds: FLIP, SSIM and
    PSNR on the displayed images; the z test on linear radiance (a render, an EXR) or, for a PNG, on
    clamp(2^exposure L) against the reference mean put through the same exposure and clamp. The keys
    starting with "_" are the pictures (FLIP's map, the rejected pixels, the image as shown)."""
    shown_ref = metrics.display(ref.mean, ref.exposure)
    if encoding.linear:
        shown, test, mean, var = metrics.display(image, ref.exposure), image, ref.mean, ref.variance
    else:
        scale = 2.0**ref.exposure
        shown, test = image, metrics.srgb_decode(image)
        mean, var = np.clip(ref.mean * scale, 0.0, 1.0), ref.variance * scale * scale
    flip_mean, flip_map = metrics.flip(shown_ref, shown)
    rejected, z, critical = metrics.pixel_test(
        test, mean, var, ref.spp, n, alpha=alpha, rounding=encoding.rounding(mean)
    )
    return {
        "flip": round(flip_mean, 6), "ssim": round(metrics.ssim(shown_ref, shown), 6),
        "psnr": round(metrics.psnr(shown_ref, shown), 4), "rejected": round(rejected, 6),
        "_flip_map": flip_map, "_rejected": z > critical, "_shown": shown,
    }  # fmt: skip


def _alpha(assignment: Assignment) -> float:
    spec = assignment.reference
    return spec.pixels.alpha if spec is not None and spec.pixels else 1e-3


def baseline_metrics(
    assignment: Assignment, ref: ReferenceImages, r: Rendered | None, key: tuple, encoding: metrics.Encoding
) -> dict:
    """The noise baseline's metrics for submissions rendered as `key` and stored as `encoding`: the
    baseline render `r` is stored the same way (a PNG's rounding, a half float's) and measured like
    them; {"error": why} when there is no baseline or no reference mean."""
    if r is None or r.error or ref.mean is None:
        return {"error": (r.error if r else None) or ref.error or "no noise baseline"}
    m = measure(ref, encoding.store(r.image, ref.exposure), key[1], encoding, _alpha(assignment))
    return {k: v for k, v in m.items() if not k.startswith("_")}


def finish_report(
    assignment: Assignment, p: Prepared, r: Rendered | None, ref: ReferenceImages | None, baseline: Callable[[], dict]
) -> Report:
    """A prepared submission's image tests (p.report, completed and returned): against `ref`, with its
    render `r` (scenes; None when it has none) or its own image (p.image), and the noise baseline's
    metrics, asked for (`baseline()`) only when the comparison is made."""
    report, tests = p.report, assignment.image_tests()
    if report.errors or not tests:
        return report
    base: dict = {}
    problem = report.metrics.get("problem") or ref.error
    if problem is None and p.sub.kind == "scene" and (r is None or r.error):
        problem = r.error if r else "not rendered"
    if problem is None:
        if r is not None:
            report.render_seconds = r.seconds
        try:
            base = baseline()
            problem = base.get("error")
            if problem is None and p.image is None:
                m = measure(ref, r.image, r.spp, p.encoding, _alpha(assignment))
            elif problem is None:
                m = measure(ref, p.image, p.key[1], p.encoding, _alpha(assignment))
        except metrics.GradingError as e:
            problem = str(e)
    if problem is not None:
        for name, t in tests.items():
            report.tests.append(TestResult(TEST_NAMES[name], 0.0, t.points, f"not compared: {problem}", "image"))
        report.metrics["problem"] = problem
        return report
    report.metrics.update({k: v for k, v in m.items() if not k.startswith("_")})
    report.metrics["baseline"] = {k: v for k, v in base.items() if not k.startswith("_")}
    report.metrics["spp"] = p.key[1]
    report.metrics["encoding"] = p.encoding.describe()
    for name, t in tests.items():
        report.tests.append(_image_test(name, t, m, base))
    _pictures(report, ref, m)
    return report


def _image_test(name: str, t, m: dict, base: dict) -> TestResult:
    if name == "pixels":
        allowed = base["rejected"] + t.max_fraction
        ok = m["rejected"] <= allowed
        text = (f"{m['rejected']:.2%} of pixels differ from the reference by more than the noise explains "
                f"(z test, alpha {t.alpha:g}); allowed {allowed:.2%} = the noise baseline's {base['rejected']:.2%}"
                f" + {t.max_fraction:.2%}")  # fmt: skip
        return TestResult(TEST_NAMES[name], t.points if ok else 0.0, t.points, text, "image")
    lower_is_better = name == "flip"
    if t.limit is not None:
        bound, how = t.limit, "the assignment's limit"
    else:
        bound = base[name] + t.margin if lower_is_better else base[name] - t.margin
        how = f"the noise baseline's {base[name]:.4g} {'+' if lower_is_better else '-'} {t.margin:g}"
    ok = m[name] <= bound if lower_is_better else m[name] >= bound
    label = {"flip": "FLIP", "ssim": "SSIM", "psnr": "PSNR"}[name]
    unit = " dB" if name == "psnr" else ""
    text = f"{label} {m[name]:.4g}{unit}; {'at most' if lower_is_better else 'at least'} {bound:.4g}{unit} ({how})"
    return TestResult(TEST_NAMES[name], t.points if ok else 0.0, t.points, text, "image")


def _pictures(report: Report, ref: ReferenceImages, m: dict) -> None:
    report.images["render"] = np.round(m["_shown"] * 255).astype(np.uint8)
    report.images["reference"] = np.round(metrics.display(ref.mean, ref.exposure) * 255).astype(np.uint8)
    report.images["error_map"] = np.round(m["_flip_map"] * 255).astype(np.uint8)
    grey = report.images["render"].mean(axis=-1, keepdims=True) * 0.5
    out = np.repeat(grey, 3, axis=-1)
    out[m["_rejected"]] = (255, 40, 40)
    report.images["rejected"] = out.astype(np.uint8)
