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
import dataclasses
import json
import math
import re
import time
import unicodedata
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
    limit_source: str = "the assignment's limits.max_seconds"  # what set max_seconds, for the message


def over_time(seconds: float, source: str) -> str:
    """Why a render has no image: it ran past its time limit, and what set that limit."""
    return f"stopped: over the time limit of {seconds:g} s per render (set by {source})"


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
                compile_scene(scene, limits=job.limits), threads=self.threads,
                cancel=lambda: time.monotonic() - start > job.max_seconds,
            )  # fmt: skip
        except SceneError as e:
            return Rendered(error="invalid scene: " + "; ".join(_error_text(x) for x in e.errors))
        if result.cancelled:
            return Rendered(error=over_time(job.max_seconds, job.limit_source))
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
                {
                    "name": t.name,
                    "number": str(i + 1),
                    "score": _round(t.score),
                    "max_score": _round(t.max_score),
                    "status": "passed" if t.passed else "failed",
                    "output": t.output,
                    "visibility": "visible",
                }
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


STUDENT_NAME_CHARS = 80  # the longest student id, in characters
STUDENT_NAME_BYTES = 240  # ... and in UTF-8 bytes (it names a folder: file systems allow 255)


def student_name(text: str) -> str:
    """A file or folder name -> a safe student id: Unicode letters, marks and digits (NFC, so a name from
    a macOS zip matches the same name typed elsewhere), '.', '_' and '-'; every other run of characters
    becomes one '_', and leading or trailing '.' and '_' go ("Zoë O'Brien" -> "Zoë_O_Brien"). The page
    asks the server for this (POST /api/grade/students) rather than keeping a copy of the rule."""
    text = unicodedata.normalize("NFC", text)
    kept = "".join(c if c in "._-" or unicodedata.category(c)[0] in "LMN" else "\0" for c in text)
    name = re.sub("\0+", "_", kept).strip("._") or "student"
    name = name[:STUDENT_NAME_CHARS]
    while len(name.encode("utf-8")) > STUDENT_NAME_BYTES:
        name = name[:-1]
    return name.rstrip("._") or "student"


def read_image(data: bytes, kind: str) -> np.ndarray:
    """A PNG (8 or 16 bit; grey, RGB or RGBA) as displayed floats in [0, 1], or an EXR as linear floats."""
    return decode_image(data, kind)[0]


def decode_image(data: bytes, kind: str) -> tuple[np.ndarray, metrics.Encoding]:
    """A student's image file -> (H, W, 3) float32 pixels and how they are encoded:
    - an EXR holds linear radiance without exposure (as `render --exr` writes it): R, G, B (or Y, grey)
      channels, 32-bit float or 16-bit half float; NaN and infinities become 0;
    - a PNG holds sRGB(clamp(2^exposure L)) in [0, 1], at its own bit depth (16-bit PNGs keep their
      16 bits; Pillow would round them to 8), grey, grey with alpha, RGB, RGBA or a palette; alpha is dropped.
    Raises GradingError for a file that is not what its kind says."""
    if kind == "exr":
        return _decode_exr(data)
    bits = _png_bit_depth(data)
    if bits == 16:
        return _decode_png16(data)
    import io

    from PIL import Image, UnidentifiedImageError

    try:
        im = Image.open(io.BytesIO(data))
        im.load()
    except (UnidentifiedImageError, OSError, ValueError) as e:
        raise metrics.GradingError(f"cannot read the PNG image: {e}") from None
    a = np.asarray(im.convert("RGBA" if "A" in im.mode or "transparency" in im.info else "RGB"), dtype=np.float64)
    return np.clip(a[..., :3] / 255.0, 0.0, 1.0).astype(np.float32), metrics.Encoding("png", bits or 8)


def _png_bit_depth(data: bytes) -> int | None:
    """The bits per sample of a PNG's pixel values, from its header (a palette's entries have 8); None: not a PNG."""
    if len(data) < 26 or data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        return None
    depth, colour = data[24], data[25]
    return 8 if colour == 3 else depth  # 3: a palette of 8-bit RGB entries


def _decode_png16(data: bytes) -> tuple[np.ndarray, metrics.Encoding]:
    import png  # pypng: Pillow has no 16-bit colour modes (it reads a 48-bit PNG as 24-bit)

    try:
        width, height, rows, info = png.Reader(bytes=data).asDirect()
        a = np.vstack([np.asarray(r, dtype=np.float64) for r in rows]).reshape(height, width, info["planes"])
    except (png.Error, ValueError, EOFError) as e:
        raise metrics.GradingError(f"cannot read the PNG image: {e}") from None
    bits = info["bitdepth"]  # 16, or fewer where an sBIT chunk says so
    a = a / float(2**bits - 1)
    a = a[..., :1] if info["greyscale"] else a[..., :3]  # alpha dropped
    return np.clip(np.broadcast_to(a, (height, width, 3)), 0.0, 1.0).astype(np.float32), metrics.Encoding("png", bits)


def _decode_exr(data: bytes) -> tuple[np.ndarray, metrics.Encoding]:
    import tempfile

    import OpenEXR

    with tempfile.NamedTemporaryFile(suffix=".exr") as f:
        f.write(data)
        f.flush()
        try:
            with OpenEXR.File(f.name, separate_channels=True) as exr:
                channels = {name: np.asarray(c.pixels) for name, c in exr.channels().items()}
        except Exception:  # OpenEXR raises plain exceptions for broken files
            raise metrics.GradingError("cannot read the EXR image: it is not an OpenEXR file") from None
    names = ["R", "G", "B"] if {"R", "G", "B"} <= set(channels) else ["Y"] * 3 if "Y" in channels else None
    if names is None:
        found = ", ".join(sorted(channels)) or "none"
        raise metrics.GradingError(f"the EXR image has no colour: R, G and B (or Y) channels wanted; it has {found}")
    if any(channels[n].dtype.kind != "f" for n in names):
        raise metrics.GradingError("the EXR image holds integers; radiance is wanted as half or full floats")
    bits = 16 if any(channels[n].dtype == np.float16 for n in names) else 32
    image = np.stack([channels[n].astype(np.float32) for n in names], axis=-1)
    return np.nan_to_num(image, nan=0.0, posinf=0.0, neginf=0.0), metrics.Encoding("exr", bits)


# ---------------------------------------------------------------------------------------- grader


@dataclass
class ReferenceImages:
    """What every comparison is made against: the reference scene's mean and per-sample variance."""

    exposure: float  # the reference scene's film.exposure (the display of every image)
    mean: np.ndarray | None = None  # (H, W, 3) linear radiance
    variance: np.ndarray | None = None  # (H, W, 3) per-sample variance of the mean's samples
    spp: int = 0  # samples of the mean
    error: str | None = None  # why there is no mean (its render failed)


@dataclass
class _Reference(ReferenceImages):
    scene: dict = field(default_factory=dict)  # the reference scene with the assignment's settings
    baselines: dict = field(default_factory=dict)  # (sampler, spp, light_samples) -> the baseline's Rendered
    measured: dict = field(default_factory=dict)  # (that key, Encoding) -> the baseline's metrics, stored that way


@dataclass
class Prepared:
    """A submission checked (validity, requirements) and the render it needs, before any image test:
    the first half of a student's grade. As plain data (`to_json`) it crosses process boundaries and
    is kept in the service's database between the two halves (server/grading.py)."""

    sub: Submission
    report: Report
    job: RenderJob | None = None  # the submission's render (scenes)
    image: np.ndarray | None = None  # the submission's image (images), in the units of its encoding
    encoding: metrics.Encoding = metrics.Encoding("render")  # how the submission holds its values
    key: tuple | None = None  # (sampler, spp, light_samples) of its noise baseline
    size: tuple[int, int, int] | None = None  # (width, height, spp) of its render, with the assignment's settings
    render_warnings: list = field(default_factory=list)  # validation warnings of that render's scene

    def to_json(self) -> dict:
        """Everything but the submission's bytes and decoded image (exact: tests keep their raw floats)."""
        r = self.report
        job = None
        if self.job is not None:
            job = {f.name: getattr(self.job, f.name) for f in dataclasses.fields(self.job)}
            job["limits"] = dataclasses.asdict(self.job.limits)
        return {
            "student": self.sub.student, "kind": self.sub.kind, "filename": self.sub.filename,
            "report": {"assignment": r.assignment, "kind": r.kind, "tests": [dataclasses.asdict(t) for t in r.tests],
                       "errors": r.errors, "warnings": r.warnings, "metrics": r.metrics},
            "job": job, "key": list(self.key) if self.key is not None else None,
            "encoding": [self.encoding.format, self.encoding.bits],
            "size": list(self.size) if self.size else None, "render_warnings": self.render_warnings,
        }  # fmt: skip

    @classmethod
    def from_json(cls, d: dict, data: bytes = b"") -> Prepared:
        r = d["report"]
        report = Report(d["student"], r["assignment"], r["kind"], [TestResult(**t) for t in r["tests"]],
                        r["errors"], r["warnings"], r["metrics"])  # fmt: skip
        job = None
        if d["job"] is not None:
            job = RenderJob(**{**d["job"], "limits": Limits(**d["job"]["limits"])})
        return cls(
            Submission(d["student"], data, d["kind"], d["filename"]), report, job,
            encoding=metrics.Encoding(*d["encoding"]), key=tuple(d["key"]) if d["key"] is not None else None,
            size=tuple(d["size"]) if d["size"] else None, render_warnings=d["render_warnings"],
        )  # fmt: skip


class Grader:
    """Grades submissions against one assignment; the reference renders are made once and kept."""

    def __init__(self, assignment: Assignment, base_dir: Path | None = None, renderer: Renderer | None = None):
        self.assignment = assignment
        self.renderer = renderer or InlineRenderer()
        self.limits = assignment.limits.scene_limits()
        self.reference: _Reference | None = None
        if assignment.reference is not None:
            scene = self._reference_scene(assignment.reference.scene, base_dir)
            exposure = float(scene.get("film", {}).get("exposure", 0.0))
            self.reference = _Reference(exposure=exposure, scene=self._settings(scene))

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
        if priority == 0:
            return RenderJob(name, scene, self.assignment.limits.max_seconds, self.limits, priority)
        seconds = self.assignment.limits.max_seconds * REFERENCE_TIME_FACTOR
        source = f"{REFERENCE_TIME_FACTOR} x the assignment's limits.max_seconds, for the reference renders"
        return RenderJob(name, scene, seconds, Limits(), priority, source)

    def reference_jobs(self, keys: set[tuple]) -> list[tuple[str, tuple | None, RenderJob]]:
        """The reference mean (once) and the noise baselines not made yet, for these (sampler, spp,
        light_samples): ("mean", None, job) and ("baseline", key, job)."""
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
        prepared = [self.prepare(s) for s in submissions]
        keys = {p.key for p in prepared if p.key is not None}
        ref_jobs = self.reference_jobs(keys) if self.reference is not None else []
        student_jobs = [p for p in prepared if p.job is not None]
        results = self.renderer([j for _, _, j in ref_jobs] + [p.job for p in student_jobs])
        for (what, key, _), r in zip(ref_jobs, results[: len(ref_jobs)], strict=True):
            self._keep_reference(what, key, r)
        rendered = dict(zip((id(p) for p in student_jobs), results[len(ref_jobs) :], strict=True))
        return [self.finish(p, rendered.get(id(p))) for p in prepared]

    def grade_one(self, submission: Submission) -> Report:
        return self.grade([submission])[0]

    def _keep_reference(self, what: str, key: tuple | None, r: Rendered) -> None:
        ref = self.reference
        if what == "mean":
            ref.mean, ref.variance, ref.spp, ref.error = r.image, r.variance, r.spp, r.error
            return
        ref.baselines[key] = r

    def _baseline(self, key: tuple, encoding: metrics.Encoding) -> dict:
        """The noise baseline's metrics for `key` and `encoding` (baseline_metrics), measured once."""
        ref = self.reference
        if (key, encoding) not in ref.measured:
            ref.measured[(key, encoding)] = baseline_metrics(
                self.assignment, ref, ref.baselines.get(key), key, encoding
            )
        return ref.measured[(key, encoding)]

    def finish(self, p: Prepared, r: Rendered | None) -> Report:
        """The second half of a grade: the image tests of a prepared submission, given its render."""
        return finish_report(self.assignment, p, r, self.reference, lambda: self._baseline(p.key, p.encoding))

    def prepare(self, sub: Submission) -> Prepared:
        """The first half of a grade: validity and requirements, and the render the image tests need."""
        a = self.assignment
        report = Report(sub.student, a.name, "scene" if sub.kind == "scene" else "image")
        p = Prepared(sub, report)
        if sub.kind in IMAGE_KINDS:
            return self._prepare_image(p)
        try:
            scene, report.warnings = load_scene(sub.data, self.limits, assets=ASSET_DIR)  # as the render will
        except SceneError as e:
            return self.refused(p, e.errors)
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
                final, p.render_warnings = load_scene(data, self.limits)
                p.key = (final.sampler.type, final.sampler.spp, final.render.light_samples)
                p.size = (final.film.width, final.film.height, final.sampler.spp)
            except SceneError as e:  # the assignment's settings made it invalid (e.g. spp for a grid)
                p.job = None
                report.metrics["problem"] = "with the assignment's settings: " + "; ".join(map(_error_text, e.errors))
        return p

    def refused(self, p: Prepared, errors: list[dict]) -> Prepared:
        """A scene that does not validate (its `errors`): it earns what validity.per_error leaves, and
        nothing else is checked."""
        a, report = self.assignment, p.report
        report.errors = errors
        cost = a.validity.points if a.validity.per_error is None else a.validity.per_error * len(errors)
        lines = [f"{len(errors)} error(s) in the scene:"] + [f"  {_error_text(x)}" for x in errors]
        report.tests.append(TestResult("valid scene", max(0.0, a.validity.points - cost), a.validity.points,
                                       "\n".join(lines), "validity"))  # fmt: skip
        for r in a.requirements:
            report.tests.append(TestResult(r.name, 0.0, r.points, "not checked: the scene is invalid", "requirement"))
        for name, t in a.image_tests().items():
            report.tests.append(TestResult(TEST_NAMES[name], 0.0, t.points, "not compared: the scene is invalid",
                                           "image"))  # fmt: skip
        return p

    def unreadable(self, p: Prepared, message: str) -> Prepared:
        """A submission that cannot be graded at all (`message` says why): an image that cannot be read,
        or a file the grader's process died on. It earns nothing."""
        if p.sub.kind == "scene":
            return self.refused(p, [{"path": "", "message": message}])
        a, report = self.assignment, p.report
        report.errors = [{"path": "", "message": message}]
        report.tests.append(TestResult("readable image", 0.0, a.validity.points, message, "validity"))
        for name, t in a.image_tests().items():
            report.tests.append(TestResult(TEST_NAMES[name], 0.0, t.points, "not compared: no image", "image"))
        return p

    def _prepare_image(self, p: Prepared) -> Prepared:
        a, report = self.assignment, p.report
        try:
            if self.reference is None:
                raise metrics.GradingError("this assignment has no reference scene to compare images with")
            p.image, p.encoding = decode_image(p.sub.data, p.sub.kind)
            w = self.reference.scene.get("film", {}).get("width", 256)
            h = self.reference.scene.get("film", {}).get("height", 256)
            if p.image.shape[:2] != (h, w):
                raise metrics.GradingError(f"the image is {p.image.shape[1]}x{p.image.shape[0]} pixels; "
                                           f"the assignment renders {w}x{h}")  # fmt: skip
        except metrics.GradingError as e:
            return self.unreadable(p, str(e))
        h, w = p.image.shape[:2]
        report.tests.append(TestResult("readable image", a.validity.points, a.validity.points,
                                       f"a {w}x{h} {p.sub.kind.upper()} image ({p.encoding.describe()})",
                                       "validity"))  # fmt: skip
        ref_scene, _ = load_scene(self.reference.scene)
        spp = a.image.spp or a.render.spp or ref_scene.sampler.spp
        p.key = (ref_scene.sampler.type, spp, ref_scene.render.light_samples)
        return p


# ------------------------------------------------------------------ the image tests, as plain functions
#
# Grader.finish and the service's worker processes (tracer/grading/tasks.py) both grade through these:
# they take the reference, the submission's image and the baseline's metrics as plain data.


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
