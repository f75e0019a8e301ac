"""The grading page in Chromium: the instructor's token entered, the example class loaded
(tests/web/test_web_grading.py and the page tests built on it)."""

from __future__ import annotations


def enter_token(page, token: str) -> None:
    page.fill("#grade-token", token)
    page.dispatch_event("#grade-token", "change")


def load_example(page) -> None:
    page.click("#grade-load-example")
    page.wait_for_function("() => document.querySelectorAll('#grade-sub-rows tr[data-student]').length === 9")
    assert '"HW 4: glass, mirrors and soft shadows"' in page.input_value("#grade-assignment")
