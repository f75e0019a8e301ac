"""Grading: a submitted scene (or a student's own image) against an assignment.

A scene earns the validity points when it validates (each error costs points, with its message),
then each requirement's points (checked on the scene as submitted), then, where the assignment
has a reference, the image tests (imagetests.py): the scene is rendered at the assignment's settings
and seed and compared with the reference scene's mean (many samples) and its noise baseline.

A grade has two halves: `Grader.prepare` (validity, requirements, and the render the image tests
need: a `Prepared`) and `Grader.finish` (the image tests, given that render). `Grader.grade` does
both for a list of submissions, with every render in one list to its `renderer` (renders.py).
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tracer.grading import metrics
from tracer.grading.checks import run_check
from tracer.grading.imagetests import TEST_NAMES, ReferenceImages, baseline_metrics, finish_report
from tracer.grading.prepared import Prepared
from tracer.grading.renders import InlineRenderer, Rendered, Renderer, RenderJob
from tracer.grading.report import Report, TestResult, error_text
from tracer.grading.spec import Assignment, AssignmentError
from tracer.grading.submission import IMAGE_KINDS, Submission, decode_image
from tracer.scene import ASSET_DIR, Limits, Mesh, SceneError, load_scene

REFERENCE_TIME_FACTOR = 10  # the reference renders may take this many times a student's limit


@dataclass
class _Reference(ReferenceImages):
    scene: dict = field(default_factory=dict)  # the reference scene with the assignment's settings
    baselines: dict = field(default_factory=dict)  # (sampler, spp, light_samples) -> the baseline's Rendered
    measured: dict = field(default_factory=dict)  # (that key, Encoding) -> the baseline's metrics, stored that way


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
        assert ref is not None and spec is not None, "asked for when the assignment has a reference scene alone"
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
        results = self.renderer([j for _, _, j in ref_jobs] + [p.job for p in student_jobs if p.job is not None])
        for (what, key, _), r in zip(ref_jobs, results[: len(ref_jobs)], strict=True):
            self._keep_reference(what, key, r)
        rendered = dict(zip((id(p) for p in student_jobs), results[len(ref_jobs) :], strict=True))
        return [self.finish(p, rendered.get(id(p))) for p in prepared]

    def grade_one(self, submission: Submission) -> Report:
        return self.grade([submission])[0]

    def _keep_reference(self, what: str, key: tuple | None, r: Rendered) -> None:
        ref = self.reference
        assert ref is not None, "reference renders are made when the assignment has a reference scene alone"
        if what == "mean":
            ref.mean, ref.variance, ref.spp, ref.error = r.image, r.variance, r.spp, r.error
            return
        ref.baselines[key] = r

    def _baseline(self, key: tuple | None, encoding: metrics.Encoding) -> dict:
        """The noise baseline's metrics for `key` and `encoding` (baseline_metrics), measured once."""
        ref = self.reference
        assert ref is not None and key is not None, "asked for when a submission is compared with the reference"
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
                assert final.sampler.spp is not None, "the Sampler's validator fills in its type's default spp"
                p.key = (final.sampler.type, final.sampler.spp, final.render.light_samples)
                p.size = (final.film.width, final.film.height, final.sampler.spp)
            except SceneError as e:  # the assignment's settings made it invalid (e.g. spp for a grid)
                p.job = None
                report.metrics["problem"] = "with the assignment's settings: " + "; ".join(map(error_text, e.errors))
        return p

    def refused(self, p: Prepared, errors: list[dict]) -> Prepared:
        """A scene that does not validate (its `errors`): it earns what validity.per_error leaves, and
        nothing else is checked."""
        a, report = self.assignment, p.report
        report.errors = errors
        cost = a.validity.points if a.validity.per_error is None else a.validity.per_error * len(errors)
        lines = [f"{len(errors)} error(s) in the scene:"] + [f"  {error_text(x)}" for x in errors]
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


def _mesh_triangles(scene) -> dict[int, int]:
    """Faces of the mesh files (for the primitive count); an unreadable file counts 0 (the render says why)."""
    from tracer.kernels.compile import load_mesh_file

    out = {}
    for i, obj in enumerate(scene.objects):
        if isinstance(obj, Mesh) and obj.file:
            try:
                out[i] = len(load_mesh_file(obj.file, f"objects[{i}].file", ASSET_DIR)[1])
            except SceneError:
                out[i] = 0
    return out
