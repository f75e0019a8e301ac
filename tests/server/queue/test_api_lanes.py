"""Interactive work first (server/jobs/lifecycle.py's lanes), on the embedded backend: a worker kept for
interactive jobs, a batch render that gives way at a pass boundary and resumes where it stopped, a
queued job's place and expected wait, and a render that continues from its last snapshot after its
worker died. Each with its own app and real worker processes."""

from __future__ import annotations

import json
import os
import signal

import numpy as np
import pytest

from tests.support.api import api_client, exr_of, submit, wait_for, wait_status
from tests.support.scene import ROOT, scene_dict, small
from tracer.rendering.progressive import render
from tracer.scene import load_scene


def long_job(spp: int = 2304, seed: int = 0, size: tuple = (128, 96)) -> dict:
    """Whitted's scene at 128 x 96: a few seconds on two threads, a dozen passes."""
    return small(scene_dict("whitted"), *size, sampler={"type": "jittered", "spp": spp}, render={"seed": seed})


def quick_job() -> dict:
    return small(scene_dict("whitted"), 16, 12, sampler={"type": "jittered", "spp": 4})


def job(client, job_id: str) -> dict:
    return client.get(f"/api/jobs/{job_id}").json()


LIBRARY: dict[str, np.ndarray] = {}  # the library's image of each scene asked for (both tests' long job is the same)


def library_image(scene: dict) -> np.ndarray:
    """The library's render of `scene` (made once in the module: a render is deterministic, bit for bit)."""
    key = json.dumps(scene, sort_keys=True)
    if key not in LIBRARY:
        LIBRARY[key] = render(load_scene(scene)[0]).image
    return LIBRARY[key].copy()


def batch(client, scene: dict) -> dict:
    r = client.post("/api/jobs", json={"scene": scene, "lane": "batch"})
    assert r.status_code == 202, r.text
    assert r.json()["lane"] == "batch"
    return r.json()


def test_api_lanes_an_interactive_worker_takes_the_page_s_jobs_while_a_batch_renders(tmp_path):
    with api_client(tmp_path / "data", workers=1, interactive_workers=1) as client:
        lanes = sorted(tuple(w["lanes"]) for w in client.get("/api/health").json()["workers"])
        assert lanes == [("interactive",), ("interactive", "batch")]
        long = batch(client, long_job(4096, size=(256, 192)))
        wait_for(lambda: job(client, long["id"])["status"] == "running", 30, "the batch render to start")
        waiting = batch(client, long_job(4096, seed=1, size=(256, 192)))  # the only batch worker is busy
        place = job(client, waiting["id"])["queue"]
        assert place["lane"] == "batch"
        assert place["position"] == 1
        assert place["ahead"] == 0
        assert place["running"] >= 1
        assert place["workers"] == 1
        assert place["expected_wait"] > 0
        quick = submit(client, quick_job())
        assert quick["lane"] == "interactive"
        assert quick["estimate"] < 1
        done = wait_status(client, quick["id"], {"done"}, timeout=30)
        assert job(client, long["id"])["status"] == "running"  # it never had to give way
        assert len(job(client, long["id"])["tries"]) == 1 and done["tries"][0]["outcome"] == "done"
        for j in (waiting, long):
            client.delete(f"/api/jobs/{j['id']}")
            wait_for(lambda j=j: job(client, j["id"])["finished"], 30, "the cancel")


def test_api_lanes_a_batch_render_gives_way_and_resumes_with_the_same_image(tmp_path):
    """One worker, none kept for interactive work: the batch render stops at its next pass, its film
    saved; the interactive job runs; the batch render continues from that pass, and its image is the
    image of an uninterrupted render, bit for bit."""
    scene = long_job()
    with api_client(tmp_path / "data", workers=1, interactive_workers=0) as client:
        long = batch(client, scene)
        wait_for(lambda: job(client, long["id"])["progress"]["passes_done"] >= 3, 60, "three passes")
        quick = submit(client, quick_job())
        wait_status(client, quick["id"], {"done"}, timeout=60)
        gave_way = job(client, long["id"])
        assert gave_way["tries"][0]["outcome"] == "gave way"
        assert gave_way["snapshot"] >= 3
        done = wait_status(client, long["id"], {"done"}, timeout=120)
        first, second = done["tries"]
        assert second["resumed_from"] == gave_way["snapshot"]
        assert second["outcome"] == "done"
        assert done["attempts"] == 1  # giving way costs no try
        assert done["progress"]["spp_done"] == 2304
        assert done["rays"]["eye"] == 128 * 96 * 2304
        assert np.array_equal(exr_of(client, long["id"]), library_image(scene))


def test_api_lanes_a_render_continues_from_its_snapshot_after_its_worker_died(tmp_path):
    scene = long_job()
    with api_client(tmp_path / "data", workers=1, interactive_workers=0, snapshot_interval=0) as client:
        j = submit(client, scene)
        running = wait_for(lambda: (x := job(client, j["id"]))["snapshot"] >= 3 and x, 60, "a snapshot of pass 3")
        pid = client.get("/api/health").json()["workers"][0]["pid"]
        os.kill(pid, signal.SIGKILL)
        done = wait_status(client, j["id"], {"done"}, timeout=120)
        assert done["attempts"] == 2
        assert [t["outcome"] for t in done["tries"]] == ["lost", "done"]
        assert done["tries"][1]["resumed_from"] >= running["snapshot"]
        assert np.array_equal(exr_of(client, j["id"]), library_image(scene))


@pytest.mark.parametrize("spp", [4096])
def test_api_lanes_a_long_render_goes_to_the_batch_lane_by_its_estimate(client, settings, spp):
    settings.interactive_seconds = 1.0
    r = client.post("/api/jobs", json={"scene": long_job(spp)})
    assert r.status_code == 202
    assert r.json()["lane"] == "batch"
    assert r.json()["estimate"] > 1.0
    client.delete(f"/api/jobs/{r.json()['id']}")
    wait_for(lambda: job(client, r.json()["id"])["finished"], 30, "the cancel")


def test_api_lanes_a_render_of_an_exploding_ray_tree_goes_to_the_batch_lane(client, settings):
    """Issue 24: a glass ball in a box of mirrors (max_depth 64, min_weight 0) was estimated as a trivial job,
    each sample's tree counted as a few rays; it is counted at the tree's bound (TRACER_MAX_TREE_RAYS)."""
    box = json.loads((ROOT / "tests" / "tracer" / "mirror_box.json").read_text())
    settings.interactive_seconds = 20.0
    r = client.post("/api/jobs", json={"scene": small(box, 256, 256, sampler={"type": "jittered", "spp": 16})})
    assert r.status_code == 202
    assert r.json()["lane"] == "batch"
    assert r.json()["estimate"] > 20.0
    client.delete(f"/api/jobs/{r.json()['id']}")
    wait_for(lambda: job(client, r.json()["id"])["finished"], 30, "the cancel")
