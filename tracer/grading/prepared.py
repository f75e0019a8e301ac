"""A submission prepared: checked (validity, requirements) and the render it needs, before any image test.

It is the handover between a grade's two halves (Grader.prepare, then the image tests of imagetests.py),
as plain data that crosses process boundaries and waits in the service's database between them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from tracer.grading import metrics
from tracer.grading.renders import RenderJob
from tracer.grading.report import Report, TestResult
from tracer.grading.submission import Submission
from tracer.scene import Limits


@dataclass
class Prepared:
    """A submission checked (validity, requirements) and the render it needs, before any image test:
    the first half of a student's grade. As plain data (`to_json`) it crosses process boundaries and
    is kept in the service's database between the two halves (server/grading/runs.py)."""

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
