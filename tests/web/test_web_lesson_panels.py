"""server/jobs/lesson_panels.json, the lessons' panels the server renders ahead, is what the page builds: the
scenes of web/js/lessons.js's `firstPanels`, in Chromium (issue #25, item 6). A lesson whose entry changed
fails here until `python -m bench.lessons --write-panels` writes the file again (the server would only
render the old scenes ahead for nothing: a student's panel is rendered when no done render has its result)."""

from __future__ import annotations

import json

from bench.lessons import first_panels, panels_text
from server.jobs.lesson_panels import PANELS, lesson_panels
from tests.support.page import Page


def test_web_lesson_panels_the_server_s_list_is_the_page_s(browser, server):
    page = Page(browser, server, {"width": 1280, "height": 800}).open("#lessons")
    try:
        panels = first_panels(page.page)
    finally:
        page.context.close()
    assert page.unexpected_errors() == []
    assert {p["lesson"] for p in panels}
    assert all(p["scene"]["film"]["width"] <= 160 for p in panels)
    written = lesson_panels()
    assert [(p["lesson"], p["index"]) for p in written] == [(p["lesson"], p["index"]) for p in panels]
    for mine, theirs in zip(written, panels, strict=True):
        assert mine["scene"] == theirs["scene"], f"{PANELS.name}: run `python -m bench.lessons --write-panels`"
    assert PANELS.read_text() == panels_text(json.loads(json.dumps(panels)))
