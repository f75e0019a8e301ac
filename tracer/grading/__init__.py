"""Automated grading of student scenes and images (issue 7): the assignment spec, requirement
checks, noise-aware image metrics, per-student reports and the class summary. docs/grading.md."""

from tracer.grading.archive import Caps, read_zip, unpack_zip
from tracer.grading.batch import (
    collect,
    group_names,
    student_for_file,
    summary,
    summary_csv,
    write_all,
    write_report,
)
from tracer.grading.grader import Grader
from tracer.grading.imagetests import ReferenceImages
from tracer.grading.metrics import GradingError
from tracer.grading.prepared import Prepared
from tracer.grading.renders import InlineRenderer, Rendered, RenderJob
from tracer.grading.report import Report, TestResult
from tracer.grading.spec import PRESETS, Assignment, AssignmentError, load_assignment
from tracer.grading.submission import Submission, read_image, student_name

__all__ = [
    "PRESETS", "Assignment", "AssignmentError", "Caps", "Grader", "GradingError", "InlineRenderer", "Prepared",
    "ReferenceImages", "RenderJob", "Rendered", "Report", "Submission", "TestResult", "collect", "group_names",
    "load_assignment", "read_image", "read_zip", "student_for_file", "student_name", "summary", "summary_csv",
    "unpack_zip", "write_all", "write_report",
]  # fmt: skip
