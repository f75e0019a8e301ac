"""A student's grade as it is reported: each test with its points and what it found, the metrics, the
pictures to look at; as JSON (report.json) and as Gradescope's results.json."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
        lines += [f"{e['path'] or f'({self.kind})'}: {e['message']}" for e in self.errors]
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


def error_text(e: dict) -> str:
    """One of a scene's errors ({path, message}) as a line of a report: "objects[3].radius: must be > 0"."""
    return f"{e['path']}: {e['message']}" if e.get("path") else e["message"]
