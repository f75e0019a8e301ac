"""The course tests' fixtures, shared by every module here without an import: the service with a test LMS linked
(`tool` and `lms`, one per module: tests/support/lms.py)."""

from __future__ import annotations

from tests.support.lms import lms, tool  # noqa: F401  (the fixtures, registered here for the folder)
