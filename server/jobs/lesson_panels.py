"""The lessons' panels at their first controls, rendered ahead (TRACER_LESSONS_AHEAD, on by default).

A lesson (web/js/lessons.js) renders its panels through the job API; at their controls' first values they
are the same scenes for every student, so at start-up the server queues each one whose result is not done
yet (server/jobs/results.py) as a render in the batch lane, behind the examples' previews, owned by no one
(the instructor's). A student's job of that scene is then done at its submit, answered with those files.
A scene the page builds otherwise than the list says is just rendered: the list only buys speed.

The scenes are in lesson_panels.json beside this file, written from the page's own code in Chromium by
`python -m bench.lessons --write-panels` (tests/web/test_web_lesson_panels.py checks it is up to date).
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from server.jobs.lifecycle import JobKind, Lane
from server.jobs.results import result_key
from server.jobs.service import JobService
from server.jobs.store import QueueFull

log = logging.getLogger(__name__)

PANELS = Path(__file__).with_name("lesson_panels.json")  # [{lesson, index, scene}]
PRIORITY = -20  # behind the examples' previews (-10): a preview shows on the first page a student sees


def lesson_panels(path: Path = PANELS) -> list[dict]:
    return json.loads(path.read_text())


def ahead(jobs: JobService, path: Path = PANELS) -> int:
    """Queue the render of every lesson panel whose result is not done, queued or running; how many."""
    try:
        panels = lesson_panels(path)
    except (OSError, ValueError) as exc:
        log.warning("no lesson panels to render ahead: %s", exc)
        return 0
    version = jobs.version
    assert version is not None  # (server/main.py starts this only where results are answered again)
    queued = 0
    for panel in panels:
        text = json.dumps(panel["scene"])
        key = result_key(text, version)
        if jobs.store.has_result(key):
            continue
        film, sampler = panel["scene"].get("film", {}), panel["scene"].get("sampler") or {}
        try:
            jobs.submit(
                text, name=f"lesson {panel['lesson']}, panel {panel['index'] + 1}"[:200], width=int(film["width"]),
                height=int(film["height"]), spp=int(sampler.get("spp", 16)), priority=PRIORITY, kind=JobKind.render,
                lane=Lane.batch, owner=None, result_key=key,
            )  # fmt: skip
        except QueueFull:
            log.warning("the lessons' panels wait: the queue is full")
            break
        queued += 1
    log.info("lesson panels rendered ahead: %d queued", queued)
    return queued
