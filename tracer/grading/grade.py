"""The names of the old grade.py, from the modules that now hold them (one concept each):
renders.py (RenderJob, Rendered, InlineRenderer), report.py (TestResult, Report), submission.py (Submission,
student_name, decode_image), prepared.py (Prepared), grader.py (Grader), imagetests.py (ReferenceImages,
finish_report, ...). server/grading.py and server/grading_run.py still import from here; import from
those modules instead (this file goes once nothing imports it)."""

from tracer.grading.grader import REFERENCE_TIME_FACTOR, Grader
from tracer.grading.imagetests import TEST_NAMES, ReferenceImages, baseline_metrics, finish_report, measure
from tracer.grading.prepared import Prepared
from tracer.grading.renders import InlineRenderer, Rendered, Renderer, RenderJob, over_time
from tracer.grading.report import Report, TestResult
from tracer.grading.submission import (
    IMAGE_KINDS,
    STUDENT_NAME_BYTES,
    STUDENT_NAME_CHARS,
    Submission,
    decode_image,
    read_image,
    student_name,
)

__all__ = [
    "IMAGE_KINDS", "REFERENCE_TIME_FACTOR", "STUDENT_NAME_BYTES", "STUDENT_NAME_CHARS", "TEST_NAMES", "Grader",
    "InlineRenderer", "Prepared", "ReferenceImages", "RenderJob", "Rendered", "Renderer", "Report", "Submission",
    "TestResult", "baseline_metrics", "decode_image", "finish_report", "measure", "over_time", "read_image",
    "student_name",
]  # fmt: skip
