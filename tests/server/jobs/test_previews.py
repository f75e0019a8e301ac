"""The example scenes' previews (server/jobs/previews.py): rendered ahead by a worker, not in the API process; served
by the scenes route; a changed example gets a new preview."""

from __future__ import annotations

import json
import shutil
import time

from server.core.settings import Settings
from server.jobs.lifecycle import JobStatus
from server.jobs.previews import Previews
from server.jobs.service import JobService
from server.jobs.store import JobStore
from tests.support.api import INSTRUCTOR, api_client, bearer, run_solutions
from tests.support.scene import SCENES


def test_previews_are_rendered_ahead_by_a_worker_and_served_by_the_scenes_route(tmp_path, tmp_path_factory):
    solutions = run_solutions(tmp_path_factory)["TRACER_CACHE_DIR"]  # the radiosity examples solved once in a run
    with api_client(
        tmp_path / "data", workers=1, previews_ahead=True, instructor_token=INSTRUCTOR, cache_dir=solutions
    ) as client:
        names = [s["name"] for s in client.get("/api/scenes").json()]
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:  # nobody asks for a picture: the worker renders them all
            states = {s["name"]: s["preview"]["state"] for s in client.get("/api/scenes").json()}
            if all(v in ("ready", "failed") for v in states.values()):
                break
            assert set(states.values()) <= {"queued", "rendering", "ready"}
            time.sleep(0.5)
        assert states == dict.fromkeys(names, "ready")
        jobs = client.get("/api/jobs?kind=preview&limit=1000", headers=bearer(INSTRUCTOR)).json()["jobs"]
        assert len(jobs) == len(names)
        assert {j["status"] for j in jobs} == {"done"}
        assert all(j["lane"] == "batch" and j["name"].startswith("preview of ") for j in jobs)
        # a student sees none of them among their jobs, but every picture
        assert client.get("/api/jobs?kind=preview").json()["jobs"] == []
        png = client.get("/api/scenes/whitted/preview.png")
        assert png.status_code == 200
        assert png.headers["content-type"] == "image/png"
        job = next(j for j in jobs if j["name"] == "preview of whitted")
        image = client.get(f"/api/jobs/{job['id']}/image", headers=bearer(INSTRUCTOR))
        assert png.content == image.content  # the worker's render, as it made it
        assert max(job["width"], job["height"]) == 160
    # a restarted server renders nothing again: every preview is on disk
    with api_client(tmp_path / "data", workers=1, previews_ahead=True, instructor_token=INSTRUCTOR) as client:
        time.sleep(1)
        again = client.get("/api/jobs?kind=preview&limit=1000", headers=bearer(INSTRUCTOR)).json()["jobs"]
        assert len(again) == len(names)
        assert {s["preview"]["state"] for s in client.get("/api/scenes").json()} == {"ready"}


class _Recording:
    """The queue's interface as far as a preview needs it: what was handed to it, in order."""

    def __init__(self, queued: list):
        self.submitted = queued.append


def test_previews_a_changed_example_gets_a_new_preview(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(SCENES / "phong.json", scenes)
    settings = Settings(data_dir=tmp_path / "data")
    store = JobStore(settings.data_dir)
    queued = []
    previews = Previews(settings, JobService(settings, store, _Recording(queued), lambda: False), scenes)
    assert previews.state("phong")["state"] == "none"
    previews.ahead()
    assert previews.state("phong")["state"] == "queued" and len(queued) == 1
    previews.ahead()  # already queued: not twice
    assert len(queued) == 1
    # the job done (its image written as a worker would): the preview is that image
    job = queued[0]
    store.save_file(job["id"], "image.png", b"\x89PNG first")
    with store._tx() as db:
        db.execute("UPDATE jobs SET status = ? WHERE id = ?", (JobStatus.done.value, job["id"]))
    assert previews.state("phong")["state"] == "ready"
    assert previews.file("phong").read_bytes() == b"\x89PNG first"
    # the example changes: its old picture is not served for it, and a new render is queued
    data = json.loads((scenes / "phong.json").read_text())
    data["background"] = [1, 0, 0]
    (scenes / "phong.json").write_text(json.dumps(data))
    assert previews.state("phong")["state"] == "none" and previews.file("phong") is None
    previews.ensure("phong")
    assert len(queued) == 2 and json.loads(queued[1]["scene"])["background"] == [1, 0, 0]


def test_previews_a_job_that_ends_while_its_state_is_read_is_ready_not_failed(tmp_path):
    """The CI failure of 2026-12-01: state() read the job once to look for its picture (still running) and once
    more for its status (done by then), and a done job without a copied picture read as "failed"."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(SCENES / "phong.json", scenes)
    settings = Settings(data_dir=tmp_path / "data")
    store = JobStore(settings.data_dir)
    queued = []
    previews = Previews(settings, JobService(settings, store, _Recording(queued), lambda: False), scenes)
    previews.ensure("phong")
    job = queued[0]
    store.save_file(job["id"], "image.png", b"\x89PNG done")
    get, reads = store.get, []

    def get_then_finish(job_id):  # the worker finishes the job right after the first read
        row = get(job_id)
        reads.append(row["status"])
        if len(reads) == 1:
            with store._tx() as db:
                db.execute("UPDATE jobs SET status = ? WHERE id = ?", (JobStatus.done.value, job_id))
        return row

    store.get = get_then_finish
    first = previews.state("phong")
    assert first["state"] in ("queued", "ready"), first  # never "failed"
    assert previews.state("phong")["state"] == "ready"
    assert previews.file("phong").read_bytes() == b"\x89PNG done"
