"""Renders answered again (server/jobs/results.py): a job whose scene a done render already made is done at
202, with that render's pictures, and is still a job of its own token's (issue #25, item 6)."""

from __future__ import annotations

import json
import shutil

import pytest

from server.jobs import lesson_panels
from server.jobs.results import renderer_version, result_key
from tests.support.api import (
    INSTRUCTOR,
    api_client,
    bearer,
    parse_sse,
    student_token,
    submit,
    tiny_scene,
    wait_finished,
    wait_for,
)


@pytest.fixture(scope="module")
def answering(tmp_path_factory):
    with api_client(
        tmp_path_factory.mktemp("answer-again"), workers=1, answer_again=True, instructor_token=INSTRUCTOR
    ) as client:
        yield client


def test_results_a_done_render_answers_the_same_scene_of_another_token_at_once(answering):
    scene = tiny_scene(seed=11)
    first = submit(answering, scene)
    assert first["status"] == "queued"
    done = wait_finished(answering, first["id"])
    assert done["status"] == "done", done
    image = answering.get(done["image_url"]).content
    rays = answering.get(f"/api/jobs/{first['id']}/aov/rays.png").content

    other = bearer(student_token())
    r = answering.post("/api/jobs", json={"scene": scene}, headers=other)
    assert r.status_code == 202, r.text
    again = r.json()
    assert again["id"] != first["id"] and again["status"] == "done" and again["finished"], again
    assert again["rays"] == done["rays"]
    assert again["progress"] == done["progress"]
    assert again["elapsed"] == pytest.approx(done["elapsed"], abs=1e-3)  # what the render cost, not 0
    assert answering.get(again["image_url"], headers=other).content == image
    assert answering.get(f"/api/jobs/{again['id']}/aov/rays.png", headers=other).content == rays
    assert answering.get(f"/api/jobs/{again['id']}/scene", headers=other).json() == scene
    with answering.stream("GET", again["events_url"], headers=other) as stream:
        events = list(parse_sse(stream.iter_lines()))
    assert events[-1][0] == "end" and events[-1][1]["status"] == "done", events

    # each job is its own token's: the other's is a 404 to either
    assert answering.get(f"/api/jobs/{again['id']}").status_code == 404
    assert answering.get(f"/api/jobs/{first['id']}", headers=other).status_code == 404
    assert answering.get(f"/api/jobs/{again['id']}/image").status_code == 404


def test_results_another_seed_or_size_is_rendered(answering):
    scene = tiny_scene(seed=12)
    assert wait_finished(answering, submit(answering, scene)["id"])["status"] == "done"
    for changed in (tiny_scene(seed=13), tiny_scene(size=17, seed=12), tiny_scene(spp=9, seed=12)):
        assert submit(answering, changed)["status"] == "queued", changed


def test_results_an_answer_keeps_its_pictures_when_its_source_is_removed(answering):
    scene = tiny_scene(seed=14)
    first = submit(answering, scene)
    image = answering.get(wait_finished(answering, first["id"])["image_url"]).content
    again = submit(answering, scene)
    assert again["status"] == "done"
    store = answering.app.state.store
    assert store.remove(first["id"])  # the janitor's removal of the older job
    assert answering.get(again["image_url"]).content == image
    third = submit(answering, scene)  # answered from the one left
    assert third["status"] == "done"
    assert answering.get(third["image_url"]).content == image
    shutil.rmtree(store.job_dir(third["id"]))
    store.remove(again["id"])
    assert submit(answering, scene)["status"] == "queued"  # the latest done one lost its files: never an empty answer


def test_results_key_is_the_canonical_scene_and_the_renderer(tmp_path):
    text = '{"b": 1, "a": {"y": [1, 2.5], "x": "é"}}'
    assert result_key(text, "v1") == result_key('{"a":{"x":"é","y":[1,2.5]},"b":1}', "v1")
    assert result_key(text, "v1") != result_key(text, "v2")
    assert result_key(text, "v1") != result_key('{"b": 2, "a": {"y": [1, 2.5], "x": "é"}}', "v1")
    sources, assets = tmp_path / "tracer", tmp_path / "assets"
    sources.mkdir()
    assets.mkdir()
    (sources / "film.py").write_text("EXPOSURE = 1\n")
    before = renderer_version(sources, assets)
    (sources / "film.py").write_text("EXPOSURE = 2\n")
    edited = renderer_version(sources, assets)
    (assets / "brick.png").write_bytes(b"png")
    assert len({before, edited, renderer_version(sources, assets)}) == 3


def test_results_lesson_panels_rendered_ahead_answer_a_student_s_panel(answering, tmp_path):
    scenes = [tiny_scene(seed=21), tiny_scene(seed=22)]
    path = tmp_path / "panels.json"
    path.write_text(json.dumps([{"lesson": "l", "index": i, "scene": s} for i, s in enumerate(scenes)]))
    jobs = answering.app.state.jobs
    assert lesson_panels.ahead(jobs, path) == 2
    assert lesson_panels.ahead(jobs, path) == 0  # queued already: not twice
    ahead = answering.get("/api/jobs", params={"scope": "all", "limit": 2}, headers=bearer(INSTRUCTOR)).json()["jobs"]
    assert {j["name"] for j in ahead} == {"lesson l, panel 1", "lesson l, panel 2"}
    assert {j["lane"] for j in ahead} == {"batch"}
    store = answering.app.state.store  # (the instructor's jobs: the test's client is not their owner)
    wait_for(lambda: all(store.get(j["id"])["status"] == "done" for j in ahead), 60, "the panels rendered ahead")
    student = submit(answering, scenes[1])
    assert student["status"] == "done"
    assert student["name"] == scenes[1].get("name")
