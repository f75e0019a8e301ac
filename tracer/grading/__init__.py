"""Automated grading of student scenes and images (issue 7): the assignment spec, requirement
checks, noise-aware image metrics, per-student reports and the class summary. docs/grading.md."""

from tracer.grading.batch import (
    collect,
    read_zip,
    student_for_file,
    summary,
    summary_csv,
    write_all,
    write_report,
)
from tracer.grading.grade import (
    Grader,
    InlineRenderer,
    Rendered,
    RenderJob,
    Report,
    Submission,
    TestResult,
    read_image,
    student_name,
)
from tracer.grading.metrics import GradingError
from tracer.grading.spec import PRESETS, Assignment, AssignmentError, load_assignment

__all__ = [
    "PRESETS", "Assignment", "AssignmentError", "Grader", "GradingError", "InlineRenderer", "RenderJob",
    "Rendered", "Report", "Submission", "TestResult", "collect", "load_assignment", "read_image", "read_zip",
    "student_for_file", "student_name", "summary", "summary_csv", "write_all", "write_report",
]  # fmt: skip
