"""The image tests, as plain functions: a submission's image (its render, or its own file) against the
reference scene's mean by FLIP, SSIM, PSNR and a per-pixel z test.

Fair to Monte Carlo noise: each image test's threshold is relative to a *noise baseline*, the
reference scene rendered exactly as the submission was (same spp, sampler and size) with another
seed. A correct scene at 4 spp is as noisy as the baseline and passes; a wrong one does not.

Each test's output says what its score means against that baseline, in words for a first graphics course: a
verdict, the numbers (the submission's, the baseline's, the allowance), and where to look when it fails; the
rejected pixels picture marks in red only what the baseline's noise does not explain (see "the pictures").

Grader.finish and the service's worker processes (tracer/grading/tasks.py) both grade through these:
they take the reference, the submission's image and the baseline's metrics as plain data.
"""

from __future__ import annotations

import base64
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracer.grading import metrics
from tracer.grading.prepared import Prepared
from tracer.grading.renders import Rendered
from tracer.grading.report import Report, TestResult
from tracer.grading.spec import Assignment, PixelTest

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
    assert ref.mean is not None and ref.variance is not None, "compared with a reference that has its mean"
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
    assert r.image is not None, "a render without an error has its image"
    m = measure(ref, encoding.store(r.image, ref.exposure), key[1], encoding, _alpha(assignment))
    return {**{k: v for k, v in m.items() if not k.startswith("_")}, "rejected_map": pack_map(m["_rejected"])}


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
    # ref is None only with a problem already (the service's failed task: not compared, with its reason)
    problem = report.metrics.get("problem") or (ref.error if ref is not None else None)
    if problem is None and p.sub.kind == "scene" and (r is None or r.error):
        problem = r.error if r else "not rendered"
    if problem is None:
        assert ref is not None, "compared with the assignment's reference"
        if r is not None:
            report.render_seconds = r.seconds
        try:
            base = baseline()
            problem = base.get("error")
            if problem is None and p.image is None:
                assert r is not None and r.image is not None, "a scene's render, without an error"
                m = measure(ref, r.image, r.spp, p.encoding, _alpha(assignment))
            elif problem is None:
                assert p.key is not None and p.image is not None, "a prepared image: its key and its pixels"
                m = measure(ref, p.image, p.key[1], p.encoding, _alpha(assignment))
        except metrics.GradingError as e:
            problem = str(e)
    if problem is not None:
        for name, t in tests.items():
            report.tests.append(TestResult(TEST_NAMES[name], 0.0, t.points, f"not compared: {problem}", "image"))
        report.metrics["problem"] = problem
        return report
    assert ref is not None and p.key is not None, "compared with the reference: a prepared submission has its key"
    report.metrics.update({k: v for k, v in m.items() if not k.startswith("_")})
    report.metrics["baseline"] = {k: v for k, v in base.items() if not k.startswith("_") and k != "rejected_map"}
    report.metrics["spp"] = p.key[1]
    report.metrics["encoding"] = p.encoding.describe()
    spp = p.key[1]
    for name, t in tests.items():
        report.tests.append(_image_test(name, t, m, base, spp, p.sub.kind))
    _pictures(report, ref, m, base, _alpha(assignment), spp)
    _probes(report, assignment, ref, m)
    return report


def _probes(report: Report, assignment: Assignment, ref: ReferenceImages, m: dict) -> None:
    """The probe pixels (probes.py): where the picture differs most, one per region of the error map, and the
    assignment's own; a student with their own tracer logs the ray trees there (docs/own-tracer.md)."""
    from tracer.grading.probes import find, flip_error

    listed = [p.model_dump() for p in assignment.reference.probes] if assignment.reference else []
    assert ref.mean is not None, "compared with a reference that has its mean"
    error = flip_error(metrics.display(ref.mean, ref.exposure), m["_shown"])
    report.metrics["probes"] = [
        p.to_json() for p in find(error, listed) if p.x < error.shape[1] and p.y < error.shape[0]
    ]


# -- the words: each image test's output, for a student in a first graphics course
#
# Each output reads in three parts: a plain verdict against the noise baseline ("a correct render at the
# same samples per pixel"), the numbers (theirs, the baseline's, what is allowed), and, when it fails,
# where to look. The score is decided above by exactly the comparisons of the numbers shown.

MEASURES = {  # what each metric measures, in one short phrase, and which way is better
    "flip": ("FLIP", "how different the two pictures look to a viewer; 0 is identical, lower is better"),
    "ssim": ("SSIM", "how alike the pictures' edges, textures and contrast are; 1 is identical, higher is better"),
    "psnr": ("PSNR", "the pixels' average error on a log scale; higher is better, 100 dB is identical"),
}  # fmt: skip
WHERE = {  # where to look when a test fails, by what the student handed in
    "scene": "compare those parts of your scene with the reference: an object's place or size, a material's "
    "colour or its kr, kt and ks, a light's position or intensity",
    "image": "compare what your ray tracer computes there with the reference: the hit, the shading terms, "
    "the shadow rays, the reflection and transmission rays",
}


def where_without_pictures(output: str, note: str) -> str:
    """An image test's output for a student who is not shown the error map and the rejected pixels (the service's
    feedback policy hides them while an image test's result is hidden): its "Where to look" line names only what
    to compare, no picture, and then `note` (when the pictures appear). Any other output is returned as it is."""
    lines = output.split("\n")
    for i, line in enumerate(lines):
        if line.startswith("Where to look: "):
            where = next((w for w in WHERE.values() if w in line), None)
            lines[i] = f"Where to look: {where}.\n{note}" if where else note
    return "\n".join(lines)


def spp_words(spp: int) -> str:
    return f"{spp} sample{'s' if spp != 1 else ''} per pixel"


def verdict_pass(spp: int) -> str:
    return f"Matches the reference as closely as a correct render with {spp_words(spp)} does."


def _image_test(name: str, t, m: dict, base: dict, spp: int = 1, kind: str = "scene") -> TestResult:
    """One image test's points and its output (see the words above); `spp`: the samples per pixel of the
    submission and its noise baseline, `kind`: scene or image (what it says to look at)."""
    correct = f"a correct render at {spp_words(spp)}"
    where = WHERE["image" if kind in ("png", "exr", "image") else "scene"]
    if name == "pixels":
        allowed = base["rejected"] + t.max_fraction
        ok = m["rejected"] <= allowed
        numbers = (f"Pixels off by more than noise explains (a z test per pixel, alpha {t.alpha:g}; fewer is "
                   f"better): yours {m['rejected']:.2%}; {correct} (the noise baseline) {base['rejected']:.2%}; "
                   f"allowed up to {allowed:.2%} (the baseline's + {t.max_fraction:.2%}).")  # fmt: skip
        if ok:
            lines = [verdict_pass(spp), numbers]
            if base["rejected"] >= 0.01:  # the case that read as failure: many pixels off, all of them noise
                lines.append(f"At {spp_words(spp)} even a correct render has this many: they are noise, not mistakes.")
        else:
            lines = [f"Differs from the reference more than noise can explain: {m['rejected']:.2%} of your pixels "
                     f"are off, where {correct} has {base['rejected']:.2%}.", numbers,
                     "Where to look: the rejected pixels picture marks in red the regions that differ beyond "
                     f"noise (the FLIP error map shows how much); {where}."]  # fmt: skip
        return TestResult(TEST_NAMES[name], t.points if ok else 0.0, t.points, "\n".join(lines), "image")
    lower_is_better = name == "flip"
    label, measures = MEASURES[name]
    unit = " dB" if name == "psnr" else ""
    sign = "+" if lower_is_better else "-"
    if t.limit is not None:
        bound, how = t.limit, "the assignment's limit"
    else:
        bound = base[name] + t.margin if lower_is_better else base[name] - t.margin
        how = f"the baseline's {sign} {t.margin:g}{unit}"
    ok = m[name] <= bound if lower_is_better else m[name] >= bound
    numbers = (f"{label} ({measures}): yours {m[name]:.4g}{unit}; {correct} (the noise baseline) "
               f"{base[name]:.4g}{unit}; allowed {'at most' if lower_is_better else 'at least'} {bound:.4g}{unit} "
               f"({how}).")  # fmt: skip
    if ok:
        first = verdict_pass(spp) if t.limit is None else f"Within the assignment's limit for {label}."
        lines = [first, numbers]
    else:
        side = "above" if lower_is_better else "below"
        first = "Differs from the reference more than noise can explain" if t.limit is None else (
            "Further from the reference than the assignment allows")  # fmt: skip
        lines = [f"{first}: {label} {m[name]:.4g}{unit} is {side} the {bound:.4g}{unit} allowed.", numbers,
                 f"Where to look: the FLIP error map (bright where the pictures differ most) and the rejected "
                 f"pixels (red); {where}."]  # fmt: skip
    return TestResult(TEST_NAMES[name], t.points if ok else 0.0, t.points, "\n".join(lines), "image")


EXAMPLE_BASELINE = {"flip": 0.05, "ssim": 0.9, "psnr": 30.0, "rejected": 0.01}  # a noise baseline, for the example


def example_misses(assignment: Assignment, kind: str = "scene", spp: int = 16) -> tuple[list[TestResult], dict]:
    """The image tests of an example submission that misses the reference by more than noise in every test, with
    example numbers, and those metrics: what the grader says for a miss (its "Where to look" lines too), for the
    service's preview of the feedback before an assignment is published (POST /api/assignments/preview-feedback)."""
    base, m = dict(EXAMPLE_BASELINE), {}
    for name, t in assignment.image_tests().items():
        if isinstance(t, PixelTest):  # "pixels"
            m["rejected"] = round(base["rejected"] + t.max_fraction + 0.1, 4)
            continue
        down = name == "flip"  # lower is better
        bound = t.limit if t.limit is not None else base[name] + t.margin if down else base[name] - t.margin
        m[name] = round(bound + 0.1 if down else bound - (6.0 if name == "psnr" else 0.2), 4)
    m = {**base, **m}
    tests = [_image_test(name, t, m, base, spp, kind) for name, t in assignment.image_tests().items()]
    return tests, {**m, "baseline": base}


# -- the pictures
#
# The rejected pixels picture must not make a correct render look wrong: at 1 sample per pixel a correct
# render has 12 % of its pixels past the z test (rare outcomes of the noise, dense where the image is noisiest:
# a soft shadow, a glossy floor), and painting them all red read as failure. So a rejected pixel is red only
# where the submission has more rejected pixels than the noise baseline has at the same place: in the
# WINDOW x WINDOW pixels around it, of the pixels rejected in exactly one of the two images, so many are the
# submission's that a fair coin (the two are alike when the scene is correct) gives as many with chance below
# DENSE (McNemar's exact test), or near the centre of such a neighbourhood (REACH). The noise baseline's map
# of rejected pixels travels with its metrics for this (`rejected_map`, packed bits). A wrong region stays red;
# the noise's rejections are drawn pale yellow ("as many as a correct render has"), and the caption
# (metrics.captions) says both with the baseline's share.

WINDOW = 9  # pixels: the side of the neighbourhood whose rejected pixels are counted
REACH = 5  # pixels: a rejected pixel within the REACH x REACH pixels around a dense window's centre is red
DENSE = 1e-5  # a neighbourhood is beyond noise when a correct render gives its count with less chance than this
# (so small, as thousands of neighbourhoods are looked at: a correct render at 40 % rejected shows about one red
# speck in 20 images; a wrong 4 x 4 pixel patch is red)
RED = (255, 40, 40)  # rejected, beyond what the noise explains
NOISE = (235, 215, 120)  # rejected, as many as a correct render has there


def pack_map(rejected: np.ndarray) -> dict:
    """An (H, W) bool map as plain data: {"shape": [H, W], "bits": base64 of its packed bits}."""
    return {"shape": list(rejected.shape), "bits": base64.b64encode(np.packbits(rejected.ravel()).tobytes()).decode()}


def unpack_map(packed: dict) -> np.ndarray:
    h, w = packed["shape"]
    bits = np.unpackbits(np.frombuffer(base64.b64decode(packed["bits"]), np.uint8), count=h * w)
    return bits.reshape(h, w).astype(bool)


def _box(a: np.ndarray, side: int = WINDOW) -> np.ndarray:
    """The sum of `a` (H, W) over the side x side pixels centred at each pixel (zero outside), by an integral
    image."""
    r = side // 2
    c = np.pad(np.pad(a.astype(np.int64), r).cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    return c[side:, side:] - c[:-side, side:] - c[side:, :-side] + c[:-side, :-side]


def beyond_noise(rejected: np.ndarray, baseline: np.ndarray | None, share: float, alpha: float) -> np.ndarray:
    """The rejected pixels (an (H, W) bool map) that lie where the submission has more of them than a correct
    render (the noise baseline's map `baseline`) has at the same place (see above): a subset of `rejected`.
    Without the baseline's map (a run measured before it was kept), against its `share` spread evenly."""
    from scipy.stats import binom

    if baseline is not None and baseline.shape == rejected.shape:
        ours, either = _box(rejected & ~baseline), _box(rejected ^ baseline)
        chance = binom.sf(ours - 1, either, 0.5)  # P(at least `ours` of the discordant pixels are the submission's)
    else:
        p = min(max(share, alpha), 1.0)
        chance = binom.sf(_box(rejected) - 1, _box(np.ones(rejected.shape, bool)), p)
    dense = (chance < DENSE).astype(np.int64)
    return rejected & (_box(dense, REACH) > 0)  # near a dense window's centre: a region's corners are red too


def _pictures(report: Report, ref: ReferenceImages, m: dict, base: dict, alpha: float, spp: int) -> None:
    assert ref.mean is not None, "compared with a reference that has its mean"
    report.images["render"] = np.round(m["_shown"] * 255).astype(np.uint8)
    report.images["reference"] = np.round(metrics.display(ref.mean, ref.exposure) * 255).astype(np.uint8)
    report.images["error_map"] = np.round(m["_flip_map"] * 255).astype(np.uint8)
    grey = 40.0 + report.images["render"].mean(axis=-1, keepdims=True) * 0.45  # the scene, dimmed, under the marks
    out = np.repeat(grey, 3, axis=-1)
    rejected = m["_rejected"]
    share = base.get("rejected", 0.0)
    red = beyond_noise(rejected, unpack_map(base["rejected_map"]) if "rejected_map" in base else None, share, alpha)
    out[rejected & ~red] = NOISE
    out[red] = RED
    report.images["rejected"] = np.round(out).astype(np.uint8)
    report.metrics["beyond_noise"] = round(float(red.mean()), 6)
    report.metrics["captions"] = {
        "error_map": "FLIP error map: black where the pictures look the same, bright where they differ most",
        "rejected": (f"rejected pixels: red where they differ beyond noise ({red.mean():.2%} of the image); pale "
                     f"yellow as many as noise makes (a correct render at {spp_words(spp)}: {share:.2%})"),
    }  # fmt: skip
