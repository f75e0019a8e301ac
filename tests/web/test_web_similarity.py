"""The dashboard's Similarity panel (web/js/course/similarity.js, issue #41 item 6) in Chromium: an assignment with
a starter scene and a class of six (five who each made their own scene from it, one who handed in a disguised copy
of another's: bench/similarity.py), the instructor opens /course#<id>, reads that there is no report yet, asks
for one with the button, and reads the flagged pair with its facts side by side under the sentence that it is
for a person to look at; no other pair is listed. axe finds no serious violation in the panel. `python -m
server` on loopback without render workers: the report reads the submissions' files, not their grades."""

from __future__ import annotations

import json
import random

import httpx
import pytest

from bench.similarity import disguised, honest, starter
from tests.support.api import INSTRUCTOR, Server, bearer
from tests.support.axe import assert_accessible
from tests.support.course_page import open_course
from tests.support.page import TEACHER
from tests.support.scene import ROOT

DEADLINE = "2100-01-01T12:00:00Z"


def spec() -> dict:
    a = json.loads((ROOT / "scenes" / "grading" / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((ROOT / "scenes" / "grading" / "reference.json").read_text())
    return a


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("web-similarity"), workers=0,
                env={"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}) as s:  # fmt: skip
        yield s


@pytest.fixture(scope="module")
def assignment(server) -> str:
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        r = c.post("/api/assignments", json={"spec": spec(), "deadline": DEADLINE, "starter": starter()})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        names = ["ann", "bea", "cid", "dan", "eve", "fay"]
        roster = "id,name,email\n" + "".join(f"{n},{n.title()},\n" for n in names)
        r = c.post(f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv"})
        assert r.status_code == 200, r.text
        tokens = {s["id"]: bearer(s["token"]) for s in r.json()["students"]}
        rng = random.Random(21)
        scenes = {n: honest(rng) for n in names[:5]}
        scenes["fay"] = disguised(rng, scenes["bea"])
        for who, scene in scenes.items():
            r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=tokens[who])
            assert r.status_code == 202, r.text
    return aid


def test_web_similarity_the_panel_asks_for_a_report_and_shows_the_flagged_pair(browser, server, assignment, tmp_path):
    p = open_course(browser, server, tmp_path)
    try:
        p.page.evaluate("(id) => { location.hash = id; }", assignment)
        p.page.wait_for_selector("#similarity-ask")
        p.page.wait_for_function("() => document.querySelector('#similarity-status').textContent.includes('No report')")
        note = p.page.text_content("#similarity-note")
        assert "for a person to look at" in note
        assert "not a finding of misconduct" in note
        p.page.click("#similarity-ask")
        p.page.wait_for_selector(".similarity-pair", timeout=120_000)
        status = p.page.text_content("#similarity-status")
        assert "1 pair(s) much closer than usual" in status, status
        pairs = p.page.eval_on_selector_all(".similarity-pair h3", "hs => hs.map(h => h.textContent)")
        assert len(pairs) == 1 and pairs[0].startswith(("bea and fay", "fay and bea")), pairs
        heads = p.page.eval_on_selector_all(".similarity-facts thead th", "ths => ths.map(t => t.textContent)")
        assert heads[0] == "Fact" and set(heads[1:3]) == {"bea", "fay"}, heads
        shared = p.page.eval_on_selector_all(".similarity-facts tr.shared", "rows => rows.length")
        assert shared >= 5
        summary = p.page.text_content("#similarity-summary")
        assert "median" in p.page.text_content("#similarity-how") and "null" not in summary, summary
        assert not p.page.is_disabled("#similarity-ask")  # done: it may be asked again
        p.shot("course-similarity", full_page=True)
        assert_accessible(p.page, "the similarity panel", "#similarity")
        p.page.set_viewport_size({"width": 390, "height": 800})  # a phone: the tables scroll in their boxes
        p.page.wait_for_timeout(100)
        wide = p.page.evaluate("() => document.documentElement.scrollWidth - document.documentElement.clientWidth")
        panel = p.page.evaluate("() => document.querySelector('#similarity').getBoundingClientRect().right")
        assert wide <= 0 and panel <= 390, (wide, panel)
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
