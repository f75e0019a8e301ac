"""Cancellation inside long launches (issue 24): a render of the glass ball in a box of mirrors, each of its
samples tens of milliseconds, stops within seconds of its DELETE, its worker alive and taking the next job;
the tree of one of its samples comes back cut at the bound (end max_tree_rays), quickly. Before, the render
was one launch per band that nothing could stop, and its worker was held until the time limit killed it."""

from __future__ import annotations

import json
import time

from tests.support.api import api_client, job, submit, wait_for, wait_status
from tests.support.scene import ROOT, small

BOX = json.loads((ROOT / "tests" / "tracer" / "mirror_box.json").read_text())
CANCEL_SECONDS = 10  # the cancel, then a trivial job, on a machine shared with other tests (launches ~0.25 s)


def test_queue_cancel_stops_a_render_of_an_exploding_tree_within_seconds(tmp_path):
    # 32 x 32 samples of up to 200 000 tree rays (and their shadow rays): a minute on two threads, the image
    # one band, whose single launch took all of it
    with api_client(tmp_path / "data", workers=1, max_tree_rays=200_000) as client:
        pid = client.get("/api/health").json()["workers"][0]["pid"]
        long = submit(client, small(BOX, 32, 32))
        wait_for(lambda: job(client, long["id"])["progress"]["samples_done"] > 0, 60, "the render's first launch")
        asked = time.monotonic()
        assert client.delete(f"/api/jobs/{long['id']}").status_code == 202
        cancelled = wait_status(client, long["id"], {"cancelled"}, timeout=CANCEL_SECONDS)
        assert cancelled["progress"]["samples_done"] < 32 * 32
        quick = submit(client, small(BOX, 2, 2, render={"max_depth": 4}))
        wait_status(client, quick["id"], {"done"}, timeout=CANCEL_SECONDS)
        assert time.monotonic() - asked < 2 * CANCEL_SECONDS
        assert [w["pid"] for w in client.get("/api/health").json()["workers"]] == [pid]  # never killed


def test_queue_cancel_a_ray_tree_of_an_exploding_tree_comes_back_cut(tmp_path):
    """The box's ray tree, at the default bound: cut, and back at once (it was held until its time limit)."""
    with api_client(tmp_path / "data", workers=1) as client:
        asked = time.monotonic()
        r = client.post("/api/raytree", json={"scene": small(BOX, 1, 1), "x": 0, "y": 0})
        assert r.status_code == 200, r.text
        assert time.monotonic() - asked < CANCEL_SECONDS
        tree = r.json()
        assert sum(1 for n in tree["nodes"] if n["kind"] != "shadow") == tree["max_tree_rays"] == 1024
        assert any(n["end"] == "max_tree_rays" for n in tree["nodes"])
