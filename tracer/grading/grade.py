"""Grading: a submitted scene (or a student's own image) against an assignment.

A scene earns the validity points when it validates (each error costs points, with its message),
then each requirement's points (checked on the scene as submitted), then, where the assignment
has a reference, the image tests: the scene is rendered at the assignment's settings and seed and
compared with the reference scene's mean (many samples) by FLIP, SSIM, PSNR and a per-pixel z test.

Fair to Monte Carlo noise: each image test's threshold is relative to a *noise baseline*, the
reference scene rendered exactly as the submission was (same spp, sampler and size) with another
seed. A correct scene at 4 spp is as noisy as the baseline and passes; a wrong one does not.

Renders go through a `renderer`: a callable that takes a list of RenderJobs and returns one
Rendered each, in order. `InlineRenderer` renders here, one after another; the service's job
queue (server/grading.py) renders them in worker processes with a time limit per job.
"""

from __future__ import annotations

import copy
import json
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tracer.grading import metrics
from tracer.grading.checks import run_check
from tracer.grading.spec import Assignment, AssignmentError
from tracer.scene import ASSET_DIR, Limits, Mesh, SceneError, load_scene

IMAGE_KINDS = ("png", "exr")
TEST_NAMES = {  # the image tests as students see them
    "flip": "FLIP against the reference", "ssim": "SSIM against the reference",
    "psnr": "PSNR against the reference", "pixels": "pixels match the reference",
}  # fmt: skip
REFERENCE_TIME_FACTOR = 10  # the reference renders may take this many times a student's limit


# ------------------------------------------------------------------------------------ rendering


@dataclass
class RenderJob:
    """One render the grader needs, as plain data (it may cross a process boundary)."""

    name: str  # who it is for: a student, "reference", "baseline 4 spp jittered"
    scene: dict  # the scene JSON, settings already applied
    max_seconds: float  # stopped (an error) past this
    limits: Limits = field(default_factory=Limits)
    priority: int = 0  # higher first (the reference renders go before the students')


@dataclass
class Rendered:
    image: np.ndarray | None = None  # (H, W, 3) float32 linear radiance
    variance: np.ndarray | None = None  # (H, W, 3) the samples' variance
    spp: int = 0
    seconds: float = 0.0
    error: str | None = None  # why there is no image


Renderer = Callable[[list[RenderJob]], list[Rendered]]


class InlineRenderer:
    """Renders in this process, one job after another (each over `threads`); a job past its
    `max_seconds` is stopped at the next pass and counts as an error."""

    def __init__(self, threads: int | None = None):
        self.threads = threads

    def __call__(self, jobs: list[RenderJob]) -> list[Rendered]:
        return [self.one(job) for job in jobs]

    def one(self, job: RenderJob) -> Rendered:
        from tracer.compile import compile_scene
        from tracer.render import render

        start = time.monotonic()
        try:
            scene, _ = load_scene(job.scene, job.limits)
            result = render(
                compile_scene(scene), threads=self.threads,
                cancel=lambda: time.monotonic() - start > job.max_seconds,
            )  # fmt: skip
        except SceneError as e:
            return Rendered(error="invalid scene: " + "; ".join(_error_text(x) for x in e.errors))
        if result.cancelled:
            return Rendered(error=f"stopped: over the time limit of {job.max_seconds:g} s per render")
        return Rendered(result.image, result.aovs["variance"], result.spp, time.monotonic() - start)


# -------------------------------------------------------------------------------------- reports


@dataclass
class TestResult:
    name: str
    score: float
    max_score: float
    output: str
    kind: str  # validity | requirement | image

    @property
    def passed(self) -> bool:
        return self.score >= self.max_score

    def to_json(self) -> dict:
        return {
            "name": self.name, "score": _round(self.score), "max_score": _round(self.max_score),
            "status": "passed" if self.passed else "failed", "output": self.output, "kind": self.kind,
        }  # fmt: skip


@dataclass
class Report:
    """One student's grade: tests with points, metrics, and the pictures (uint8 sRGB) to look at."""

    student: str
    assignment: str
    kind: str  # scene | image
    tests: list[TestResult] = field(default_factory=list)
    errors: list[dict] = field(default_factory=list)  # the scene's errors ({path, message})
    warnings: list[dict] = field(default_factory=list)
    metrics: dict = field(default_factory=dict)  # flip, ssim, psnr, rejected (and the baseline's)
    images: dict[str, np.ndarray] = field(default_factory=dict)  # render, reference, error_map, rejected
    render_seconds: float = 0.0

    @property
    def score(self) -> float:
        return sum(t.score for t in self.tests)

    @property
    def max_score(self) -> float:
        return sum(t.max_score for t in self.tests)

    @property
    def status(self) -> str:
        """graded; invalid (the submission could not be read or validated); failed (no render)."""
        if self.errors:
            return "invalid"
        if "problem" in self.metrics:  # the image tests could not be made (no render, no reference)
            return "failed"
        return "graded"

    def to_json(self) -> dict:
        return {
            "student": self.student, "assignment": self.assignment, "kind": self.kind, "status": self.status,
            "score": _round(self.score), "max_score": _round(self.max_score),
            "tests": [t.to_json() for t in self.tests], "errors": self.errors, "warnings": self.warnings,
            "metrics": self.metrics, "render_seconds": round(self.render_seconds, 3),
            "images": sorted(self.images),
        }  # fmt: skip

    def gradescope(self) -> dict:
        """Gradescope's autograder results.json: a test per requirement, with score and max_score."""
        lines = [f"{self.assignment}: {_round(self.score)} / {_round(self.max_score)} points ({self.status})"]
        lines += [f"{e['path'] or '(scene)'}: {e['message']}" for e in self.errors]
        return {
            "score": _round(self.score),
            "output": "\n".join(lines),
            "visibility": "visible",
            "stdout_visibility": "hidden",
            "tests": [
                {"name": t.name, "number": str(i + 1), "score": _round(t.score), "max_score": _round(t.max_score),
                 "status": "passed" if t.passed else "failed", "output": t.output, "visibility": "visible"}
                for i, t in enumerate(self.tests)
            ],  # fmt: skip
        }


def _round(x: float) -> float:
    return round(float(x), 6)


def _error_text(e: dict) -> str:
    return f"{e['path']}: {e['message']}" if e.get("path") else e["message"]


# ------------------------------------------------------------------------------------ submissions


@dataclass
class Submission:
    """What a student handed in: a scene (JSON bytes) or an image (PNG or EXR bytes)."""

    student: str
    data: bytes
    kind: str = "scene"  # scene | png | exr
    filename: str = ""


def student_name(text: str) -> str:
    """A file or folder name -> a safe student id (letters, digits, . _ -)."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._") or "student"
    return name[:80]


def read_image(data: bytes, kind: str) -> np.ndarray:
    """A PNG (8 or 16 bit; grey, RGB or RGBA) as displayed floats in [0, 1], or an EXR as linear floats."""
    import io

    if kind == "exr":
        import tempfile

        from tracer.film import read_exr

        with tempfile.NamedTemporaryFile(suffix=".exr") as f:
            f.write(data)
            f.flush()
            try:
                image = read_exr(f.name)
            except Exception:  # OpenEXR raises plain exceptions for broken files
                raise metrics.GradingError("cannot read the EXR image: it is not an OpenEXR file") from None
        return np.nan_to_num(image.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    from PIL import Image, UnidentifiedImageError

    try:
        im = Image.open(io.BytesIO(data))
        im.load()
    except (UnidentifiedImageError, OSError, ValueError) as e:
        raise metrics.GradingError(f"cannot read the PNG image: {e}") from None
    if im.mode in ("I;16", "I;16B", "I"):
        a = np.asarray(im, dtype=np.float64) / 65535.0
    else:
        a = np.asarray(im.convert("RGBA" if "A" in im.mode else "RGB"), dtype=np.float64) / 255.0
    if a.ndim == 2:
        a = np.stack([a, a, a], axis=-1)
    return np.clip(a[..., :3], 0.0, 1.0).astype(np.float32)


# ---------------------------------------------------------------------------------------- grader


@dataclass
class _Reference:
    scene: dict  # the reference scene with the assignment's settings
    exposure: float
    mean: np.ndarray | None = None
    variance: np.ndarray | None = None
    spp: int = 0
    error: str | None = None
    baselines: dict = field(default_factory=dict)  # (sampler, spp, light_samples) -> the baseline's metrics


@dataclass
class _Prepared:
    sub: Submission
    report: Report
    job: RenderJob | None = None  # the submission's render (scenes)
    image: np.ndarray | None = None  # the submission's image (images): displayed or linear
    key: tuple | None = None  # (sampler, spp, light_samples) of its noise baseline


class Grader:
    """Grades submissions against one assignment; the reference renders are made once and kept."""

    def __init__(self, assignment: Assignment, base_dir: Path | None = None, renderer: Renderer | None = None):
        self.assignment = assignment
        self.renderer = renderer or InlineRenderer()
        self.limits = assignment.limits.scene_limits()
        self.reference: _Reference | None = None
        if assignment.reference is not None:
            scene = self._reference_scene(assignment.reference.scene, base_dir)
            self.reference = _Reference(self._settings(scene), float(scene.get("film", {}).get("exposure", 0.0)))

    # -- the settings every render uses

    def _reference_scene(self, src: str | dict, base_dir: Path | None) -> dict:
        if isinstance(src, dict):
            data = copy.deepcopy(src)
        else:
            if base_dir is None:
                raise AssignmentError([{"path": "reference.scene", "message": "give the scene inline: a file name "
                                        "only works for an assignment read from a file"}])  # fmt: skip
            path = (base_dir / src).resolve()
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError) as e:
                raise AssignmentError([{"path": "reference.scene", "message": f"cannot read {src}: {e}"}]) from None
        try:
            load_scene(data)
        except SceneError as e:
            raise AssignmentError(
                [{"path": "reference.scene" + ("." + x["path"] if x["path"] else ""), "message": x["message"]}
                 for x in e.errors]
            ) from None  # fmt: skip
        return data

    def _settings(self, data: dict) -> dict:
        """The assignment's render settings applied to a scene dict (a copy)."""
        out = copy.deepcopy(data)
        o = self.assignment.render
        ref = self.reference.scene if self.reference else {}

        def put(section: str, key: str, value: Any) -> None:
            if value is not None:
                if not isinstance(out.get(section), dict):
                    out[section] = {}
                out[section][key] = value

        put("film", "width", o.width or ref.get("film", {}).get("width"))
        put("film", "height", o.height or ref.get("film", {}).get("height"))
        put("sampler", "type", o.sampler)
        put("sampler", "spp", o.spp)
        put("render", "seed", o.seed)
        put("render", "integrator", o.integrator)
        put("render", "max_depth", o.max_depth)
        return out

    def _job(self, name: str, scene: dict, priority: int = 0) -> RenderJob:
        """A student's render has the assignment's limits; the instructor's (priority > 0) the defaults."""
        limits = self.limits if priority == 0 else Limits()
        seconds = self.assignment.limits.max_seconds * (1 if priority == 0 else REFERENCE_TIME_FACTOR)
        return RenderJob(name, scene, seconds, limits, priority)

    def _reference_jobs(self, keys: set[tuple]) -> list[tuple[str, tuple | None, RenderJob]]:
        """The reference mean (once) and the noise baselines not made yet, for these (sampler, spp)."""
        ref, spec = self.reference, self.assignment.reference
        jobs = []
        if ref.mean is None and ref.error is None:
            scene = copy.deepcopy(ref.scene)
            root = math.isqrt(spec.spp)
            kind = "jittered" if root * root == spec.spp else "random"  # an unbiased mean and a true variance
            scene.setdefault("sampler", {}).update(type=kind, spp=spec.spp)
            scene.setdefault("render", {})["seed"] = spec.seed
            jobs.append(("mean", None, self._job("reference", scene, priority=10)))
        for key in sorted(keys - set(ref.baselines)):
            scene = copy.deepcopy(ref.scene)
            scene.setdefault("sampler", {}).update(type=key[0], spp=key[1])
            scene.setdefault("render", {}).update(seed=spec.seed + 1, light_samples=key[2])
            name = f"baseline: {key[1]} spp {key[0]}, {key[2]} light samples"
            jobs.append(("baseline", key, self._job(name, scene, priority=5)))
        return jobs

    # -- grading

    def grade(self, submissions: list[Submission]) -> list[Report]:
        """Grade every submission; all the renders go to the renderer in one list (so a job queue
        can run them side by side), the reference ones first."""
        prepared = [self._prepare(s) for s in submissions]
        keys = {p.key for p in prepared if p.key is not None}
        ref_jobs = self._reference_jobs(keys) if self.reference is not None else []
        student_jobs = [p for p in prepared if p.job is not None]
        results = self.renderer([j for _, _, j in ref_jobs] + [p.job for p in student_jobs])
        for (what, key, _), r in zip(ref_jobs, results[: len(ref_jobs)], strict=True):
            self._keep_reference(what, key, r)
        rendered = dict(zip((id(p) for p in student_jobs), results[len(ref_jobs) :], strict=True))
        return [self._finish(p, rendered.get(id(p))) for p in prepared]

    def grade_one(self, submission: Submission) -> Report:
        return self.grade([submission])[0]

    def _keep_reference(self, what: str, key: tuple | None, r: Rendered) -> None:
        ref = self.reference
        if what == "mean":
            ref.mean, ref.variance, ref.spp, ref.error = r.image, r.variance, r.spp, r.error
            return
        if r.error or ref.mean is None:
            ref.baselines[key] = {"error": r.error or ref.error}
            return
        m = self._compare(r.image, key[1], linear=True)
        ref.baselines[key] = {k: v for k, v in m.items() if not k.startswith("_")}

    def _prepare(self, sub: Submission) -> _Prepared:
        a = self.assignment
        report = Report(sub.student, a.name, "scene" if sub.kind == "scene" else "image")
        p = _Prepared(sub, report)
        if sub.kind in IMAGE_KINDS:
            return self._prepare_image(p)
        try:
            scene, report.warnings = load_scene(sub.data, self.limits, assets=ASSET_DIR)  # as the render will
        except SceneError as e:
            report.errors = e.errors
            cost = a.validity.points if a.validity.per_error is None else a.validity.per_error * len(e.errors)
            lines = [f"{len(e.errors)} error(s) in the scene:"] + [f"  {_error_text(x)}" for x in e.errors]
            report.tests.append(TestResult("valid scene", max(0.0, a.validity.points - cost), a.validity.points,
                                           "\n".join(lines), "validity"))  # fmt: skip
            for r in a.requirements:
                text = "not checked: the scene is invalid"
                report.tests.append(TestResult(r.name, 0.0, r.points, text, "requirement"))
            for name, t in a.image_tests().items():
                report.tests.append(TestResult(TEST_NAMES[name], 0.0, t.points, "not compared: the scene is invalid",
                                               "image"))  # fmt: skip
            return p
        report.tests.append(TestResult("valid scene", a.validity.points, a.validity.points, "the scene is valid",
                                       "validity"))  # fmt: skip
        triangles = _mesh_triangles(scene)
        for r in a.requirements:
            ok, found = run_check(scene, r.check, triangles)
            text = ("passed: " if ok else "failed: ") + found + (f"\n{r.description}" if r.description else "")
            report.tests.append(TestResult(r.name, r.points if ok else 0.0, r.points, text, "requirement"))
        if self.reference is not None:
            data = self._settings(json.loads(sub.data))
            p.job = self._job(sub.student, data)
            try:
                final, _ = load_scene(data, self.limits)
                p.key = (final.sampler.type, final.sampler.spp, final.render.light_samples)
            except SceneError as e:  # the assignment's settings made it invalid (e.g. spp for a grid)
                p.job = None
                report.metrics["problem"] = "with the assignment's settings: " + "; ".join(map(_error_text, e.errors))
        return p

    def _prepare_image(self, p: _Prepared) -> _Prepared:
        a, report = self.assignment, p.report
        tests = a.image_tests()
        try:
            if self.reference is None:
                raise metrics.GradingError("this assignment has no reference scene to compare images with")
            p.image = read_image(p.sub.data, p.sub.kind)
            w = self.reference.scene.get("film", {}).get("width", 256)
            h = self.reference.scene.get("film", {}).get("height", 256)
            if p.image.shape[:2] != (h, w):
                raise metrics.GradingError(f"the image is {p.image.shape[1]}x{p.image.shape[0]} pixels; "
                                           f"the assignment renders {w}x{h}")  # fmt: skip
        except metrics.GradingError as e:
            report.errors = [{"path": "", "message": str(e)}]
            report.tests.append(TestResult("readable image", 0.0, a.validity.points, str(e), "validity"))
            for name, t in tests.items():
                report.tests.append(TestResult(TEST_NAMES[name], 0.0, t.points, "not compared: no image", "image"))
            return p
        h, w = p.image.shape[:2]
        report.tests.append(TestResult("readable image", a.validity.points, a.validity.points,
                                       f"a {w}x{h} {p.sub.kind.upper()} image", "validity"))  # fmt: skip
        ref_scene, _ = load_scene(self.reference.scene)
        spp = a.image.spp or a.render.spp or ref_scene.sampler.spp
        p.key = (ref_scene.sampler.type, spp, ref_scene.render.light_samples)
        return p

    def _compare(self, image: np.ndarray, n: int, linear: bool) -> dict:
        """Metrics of an image against the reference mean (image: linear radiance, or displayed PNG values)."""
        ref, spec = self.reference, self.assignment.reference
        shown_ref = metrics.display(ref.mean, ref.exposure)
        if linear:
            shown, lin, quantised = metrics.display(image, ref.exposure), image, False
        else:
            shown, lin, quantised = image, metrics.srgb_decode(image) / 2.0**ref.exposure, True
        mean, var = ref.mean, ref.variance
        if quantised:  # a PNG holds clamp(2^e L): compare in those units
            scale = 2.0**ref.exposure
            mean, var, lin = ref.mean * scale, ref.variance * scale * scale, lin * scale
        flip_mean, flip_map = metrics.flip(shown_ref, shown)
        alpha = spec.pixels.alpha if spec.pixels else 1e-3
        rejected, z, critical = metrics.pixel_test(lin, mean, var, ref.spp, n, alpha=alpha, quantised=quantised)
        return {
            "flip": round(flip_mean, 6), "ssim": round(metrics.ssim(shown_ref, shown), 6),
            "psnr": round(metrics.psnr(shown_ref, shown), 4), "rejected": round(rejected, 6),
            "_flip_map": flip_map, "_rejected": z > critical, "_shown": shown,
        }  # fmt: skip

    def _finish(self, p: _Prepared, r: Rendered | None) -> Report:
        report, tests = p.report, self.assignment.image_tests()
        if p.report.errors or not tests:
            return report
        ref = self.reference
        base = ref.baselines.get(p.key, {})
        problem = report.metrics.get("problem") or ref.error or base.get("error")
        if problem is None and p.sub.kind == "scene" and (r is None or r.error):
            problem = r.error if r else "not rendered"
        if problem is None:
            if r is not None:
                report.render_seconds = r.seconds
            try:
                m = self._compare(r.image, r.spp, True) if p.image is None else self._compare(p.image, p.key[1], False)
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
        for name, t in tests.items():
            report.tests.append(self._image_test(name, t, m, base))
        self._pictures(report, m)
        return report

    def _image_test(self, name: str, t, m: dict, base: dict) -> TestResult:
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

    def _pictures(self, report: Report, m: dict) -> None:
        ref = self.reference
        report.images["render"] = np.round(m["_shown"] * 255).astype(np.uint8)
        report.images["reference"] = np.round(metrics.display(ref.mean, ref.exposure) * 255).astype(np.uint8)
        report.images["error_map"] = np.round(m["_flip_map"] * 255).astype(np.uint8)
        grey = report.images["render"].mean(axis=-1, keepdims=True) * 0.5
        out = np.repeat(grey, 3, axis=-1)
        out[m["_rejected"]] = (255, 40, 40)
        report.images["rejected"] = out.astype(np.uint8)


def _mesh_triangles(scene) -> dict[int, int]:
    """Faces of the mesh files (for the primitive count); an unreadable file counts 0 (the render says why)."""
    from tracer.compile import load_mesh_file

    out = {}
    for i, obj in enumerate(scene.objects):
        if isinstance(obj, Mesh) and obj.file:
            try:
                out[i] = len(load_mesh_file(obj.file, f"objects[{i}].file", ASSET_DIR)[1])
            except SceneError:
                out[i] = 0
    return out
