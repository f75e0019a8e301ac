"""Jobs through the TestClient, rendered by a real worker process (conftest.py's `client`): life, images,
cancel, limits."""

from __future__ import annotations

import io
import json
import time

import numpy as np
import pytest
from PIL import Image

from tests.support.api import (
    bearer,
    exr_of,
    job,
    long_scene,
    parse_sse,
    student_token,
    submit,
    tiny_scene,
    wait_finished,
    wait_for,
    wait_status,
)
from tests.support.scene import scene_dict, small


@pytest.fixture
def busy(client):
    """A long job holding the only worker (cancelled afterwards); yields its id once it renders."""
    long = submit(client, long_scene(), priority=100)
    wait_status(client, long["id"], {"running"})
    yield long["id"]
    client.delete(f"/api/jobs/{long['id']}")
    wait_finished(client, long["id"])


def test_api_jobs_life_events_previews_and_the_same_pixels_as_the_library(client, compiled_kernels):
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.film import png_bytes
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    scene = tiny_scene(32, spp=16, seed=7)
    created = submit(client, scene)
    assert created["status"] in ("queued", "running")
    assert created["progress"]["samples_total"] == 32 * 32 * 16
    assert created["finished"] is False
    with client.stream("GET", created["events_url"]) as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        events = list(parse_sse(r.iter_lines()))
    kinds = [e for e, _ in events]
    assert kinds[-1] == "end" and kinds.count("end") == 1, kinds
    assert "progress" in kinds
    assert "preview" in kinds
    end = events[-1][1]
    assert end["status"] == "done"
    assert end["finished"] is True
    assert end["progress"]["fraction"] == 1.0
    assert end["eta"] is None
    assert end["rays"]["eye"] == 32 * 32 * 16
    assert end["rays"]["total"] >= end["rays"]["eye"]
    assert end["elapsed"] > 0
    assert end["attempts"] == 1
    assert end["error"] is None
    previews = [d for e, d in events if e == "preview"]
    assert previews[-1]["pass"] == end["preview"]
    assert f"pass={end['preview']}" in previews[-1]["url"]
    fractions = [d["fraction"] for e, d in events if e == "progress"]
    assert fractions == sorted(fractions)
    assert fractions[-1] == 1.0

    # the final image: the same floats as the library's render of the same scene and seed
    expected = render(compile_scene(load_scene(scene)[0]))
    np.testing.assert_array_equal(exr_of(client, created["id"]), expected.image)  # bit for bit
    png = client.get(previews[-1]["url"])
    assert png.status_code == 200
    assert png.headers["content-type"] == "image/png"
    assert png.headers["cache-control"] == "no-store"
    np.testing.assert_array_equal(
        np.asarray(Image.open(io.BytesIO(png.content))), np.asarray(Image.open(io.BytesIO(png_bytes(expected.image))))
    )
    listed = client.get("/api/jobs").json()
    assert created["id"] in [j["id"] for j in listed["jobs"]]
    assert listed["count"] >= 1
    done = client.get("/api/jobs", params={"status": "done"}).json()["jobs"]
    assert all(j["status"] == "done" for j in done)


def test_api_jobs_warnings_come_back_with_the_job(client):
    scene = tiny_scene()
    scene["fog"] = {"density": 0, "color": [1, 1, 1]}
    created = submit(client, scene)
    assert {"path": "fog.color", "message": "has no effect: fog density is 0"} in created["warnings"]
    wait_status(client, created["id"], {"done"})


def test_api_jobs_previews_arrive_while_a_long_job_runs_and_cancel_keeps_the_last(client):
    created = submit(client, long_scene())
    first = wait_for(lambda: job(client, created["id"])["preview"] >= 1, 60, "a first preview")
    assert first
    running = job(client, created["id"])
    assert running["status"] == "running"
    assert 0 < running["progress"]["fraction"] < 1
    assert running["eta"] is not None
    assert running["eta"] > 0
    assert running["elapsed"] > 0
    png = client.get(running["image_url"])
    assert png.status_code == 200
    assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
    assert Image.open(io.BytesIO(png.content)).size == (192, 144)

    asked = time.monotonic()
    r = client.delete(f"/api/jobs/{created['id']}")
    assert r.status_code == 202
    assert r.json()["cancel_requested"] is True
    assert r.json()["finished"] is False
    ended = wait_status(client, created["id"], {"cancelled"}, timeout=10)
    assert time.monotonic() - asked < 3  # the worker looks at the job between bands of rows, not only passes
    assert ended["preview"] >= 1
    assert ended["progress"]["spp_done"] < 1024
    image = exr_of(client, created["id"])
    assert image.shape == (144, 192, 3) and np.isfinite(image).all() and image.max() > 0
    again = client.delete(f"/api/jobs/{created['id']}")
    assert again.status_code == 409
    assert "already ended" in again.json()["errors"][0]["message"]


def test_api_jobs_cancel_a_queued_job(client, busy):
    waiting = submit(client, tiny_scene())
    assert job(client, waiting["id"])["status"] == "queued"
    r = client.delete(f"/api/jobs/{waiting['id']}")
    assert r.status_code == 200
    assert r.json()["status"] == "cancelled"
    assert r.json()["finished"] is True
    nothing = client.get(f"/api/jobs/{waiting['id']}/image")
    assert nothing.status_code == 404
    assert "no image yet" in nothing.json()["errors"][0]["message"]
    assert job(client, waiting["id"])["started_at"] is None


def test_api_jobs_run_by_priority_then_age(client, busy):
    low = submit(client, tiny_scene(), priority=-5)
    first = submit(client, tiny_scene(), priority=5)
    second = submit(client, tiny_scene(), priority=5)
    client.delete(f"/api/jobs/{busy}")
    ends = [wait_status(client, j["id"], {"done"}) for j in (first, second, low)]
    starts = [e["started_at"] for e in ends]
    assert starts == sorted(starts), starts


def test_api_jobs_queue_limit_answers_429(client, settings, busy):
    settings.max_queued_jobs = 2
    queued = [submit(client, tiny_scene()) for _ in range(2)]
    r = client.post("/api/jobs", json={"scene": tiny_scene()})
    assert r.status_code == 429
    assert r.headers["retry-after"]
    assert "queue is full" in r.json()["errors"][0]["message"]
    for j in queued:
        client.delete(f"/api/jobs/{j['id']}")


def test_api_jobs_queue_limit_per_token_answers_429(client, settings, busy):
    settings.max_queued_per_token = 2
    queued = [submit(client, tiny_scene()) for _ in range(2)]
    r = client.post("/api/jobs", json={"scene": tiny_scene()})
    assert r.status_code == 429
    assert r.headers["retry-after"]
    assert "TRACER_MAX_QUEUED_PER_TOKEN" in r.json()["errors"][0]["message"]
    someone = bearer(student_token())
    other = client.post("/api/jobs", json={"scene": tiny_scene()}, headers=someone)
    assert other.status_code == 202  # another student is not held back
    client.delete(f"/api/jobs/{other.json()['id']}", headers=someone)
    for j in queued:
        client.delete(f"/api/jobs/{j['id']}")


@pytest.fixture
def fast_machine(client):
    """Finished renders that took a hundredth of their estimates: the service now expects renders to be
    ten times quicker than its cost model says (its lower bound), and accepts longer ones. Removed after."""
    store = client.app.state.store
    ids = []
    now = time.time()
    for _ in range(50):  # the last 50 finished renders are what pace() reads
        row = store.create("{}", name="past", width=1, height=1, spp=1, priority=-100, warnings=[],
                           max_seconds=1, max_queued=10_000, estimate=100.0)  # fmt: skip
        store.db.execute(
            "UPDATE jobs SET status = 'done', started_at = ?, finished_at = ? WHERE id = ?", (now - 1, now, row["id"])
        )
        ids.append(row["id"])
    assert store.pace() == 0.1
    yield store
    for job_id in ids:
        store.remove(job_id)


def test_api_jobs_refused_when_its_estimate_is_past_the_limit(client, settings):
    settings.max_job_seconds = 1.0
    r = client.post("/api/jobs", json={"scene": long_scene()})
    assert r.status_code == 422
    (error,) = r.json()["errors"]
    assert error["path"] == "sampler.spp"
    assert "192 x 144 pixels x 1024 samples" in error["message"]
    assert "past the limit of 1 s per job (TRACER_MAX_JOB_SECONDS)" in error["message"]


def radiosity_scene(seed: int, **radiosity) -> dict:
    """The radiosity Cornell box, small, with a seed of its own (a radiosity solution is kept by what it solves,
    the seed included: another test's solution never serves this one)."""
    scene = small(scene_dict("cornell_radiosity"), 24, 24, sampler={"type": "jittered", "spp": 1})
    scene["render"]["seed"] = seed
    scene["render"]["radiosity"].update(radiosity)
    return scene


def test_api_jobs_radiosity_past_its_patches_or_rays_is_refused_at_submit(client):
    """A patch_size that would cut the box into more than TRACER_MAX_PATCHES patches, and rays x max_steps
    past TRACER_MAX_SOLVE_RAYS, are refused at submit at their fields, counted before anything is meshed."""
    r = client.post("/api/jobs", json={"scene": radiosity_scene(1, patch_size=0.001)})
    assert r.status_code == 422
    (error,) = r.json()["errors"]
    assert error["path"] == "render.radiosity.patch_size"
    assert error["message"].startswith(
        "patches of 0.001 cut the surfaces into 25760000 patches (objects[0] (quad): 4000000, "
    )
    assert error["message"].endswith("must be at most 100000 (limit max_patches): use a larger patch_size")
    r = client.post("/api/jobs", json={"scene": radiosity_scene(1, rays=1_000_000, max_steps=100_000)})
    assert r.status_code == 422
    assert [e["path"] for e in r.json()["errors"]] == ["render.radiosity.rays"]


def test_api_jobs_radiosity_solve_past_the_job_limit_is_refused_at_submit(client, settings):
    """A render whose radiosity solve alone is estimated past TRACER_MAX_JOB_SECONDS is refused at
    render.radiosity (not at the samples, which would not help)."""
    settings.max_job_seconds = 0.001
    r = client.post("/api/jobs", json={"scene": radiosity_scene(2)})
    assert r.status_code == 422
    (error,) = r.json()["errors"]
    assert error["path"] == "render.radiosity"
    assert error["message"].startswith("its radiosity solve would take about")
    assert "past the limit of 0.001 s per job (TRACER_MAX_JOB_SECONDS)" in error["message"]


def test_api_jobs_raytree_of_a_radiosity_scene_not_yet_solved_past_its_limit_is_refused_before_solving(
    client, settings
):
    """A ray tree whose radiosity solve is estimated past TRACER_MAX_RAYTREE_SECONDS is refused (422 at
    render.radiosity) by its worker before it solves anything; once a render of the scene has solved it, the
    solution is kept and the same ray tree is traced at once."""
    cache = settings.data_dir / "cache" / "radiosity"
    scene = radiosity_scene(31337)
    settings.max_raytree_seconds = 0.001
    before = set(cache.glob("*.npz"))
    r = client.post("/api/raytree", json={"scene": scene, "x": 12, "y": 12})
    assert r.status_code == 422, r.text
    (error,) = r.json()["errors"]
    assert error["path"] == "render.radiosity"
    assert error["message"].startswith("the radiosity solve would take about")
    assert (
        "past the ray tree's limit of 0.001 s (TRACER_MAX_RAYTREE_SECONDS): render the scene first" in error["message"]
    )
    assert set(cache.glob("*.npz")) == before  # nothing was solved
    rendered = wait_finished(client, submit(client, scene)["id"], timeout=120)
    assert rendered["status"] == "done", rendered["error"]
    assert len(set(cache.glob("*.npz")) - before) == 1  # the render's solution, kept
    r = client.post("/api/raytree", json={"scene": scene, "x": 12, "y": 12})
    assert r.status_code == 200, r.text  # the kept solution is already paid for


def test_api_jobs_over_its_time_limit_is_stopped_and_failed(client, settings, fast_machine):
    """A render that takes longer than estimated is still stopped at the limit."""
    settings.max_job_seconds = 1.0
    created = submit(client, long_scene())
    ended = wait_status(client, created["id"], {"failed"}, timeout=20)
    assert "time limit of 1 s" in ended["error"]
    assert "TRACER_MAX_JOB_SECONDS" in ended["error"]
    assert ended["finished"] is True
    assert ended["elapsed"] < 5
    assert ended["preview"] >= 1  # the last pass's image is kept
    assert client.get(f"/api/jobs/{created['id']}/image").status_code == 200


def test_api_jobs_missing_asset_is_refused_at_submit(client):
    scene = tiny_scene()
    scene["objects"].append({"type": "mesh", "file": "no_such_mesh.obj", "material": {"kd": 0.5}})
    r = client.post("/api/jobs", json={"scene": scene})
    assert r.status_code == 422
    path = f"objects[{len(scene['objects']) - 1}].file"
    assert [e["path"] for e in r.json()["errors"]] == [path]
    assert "not found" in r.json()["errors"][0]["message"]


def test_api_jobs_events_of_a_finished_job_end_at_once(client):
    created = submit(client, tiny_scene())
    wait_status(client, created["id"], {"done"})
    with client.stream("GET", f"/api/jobs/{created['id']}/events") as r:
        events = list(parse_sse(r.iter_lines()))
    assert [e for e, _ in events] == ["progress", "preview", "end"]
    assert json.dumps(events[-1][1])  # plain JSON


def test_api_jobs_every_example_scene_renders_as_the_library_does(client, settings, compiled_kernels):
    """Each example (every integrator and sampler), small, through the worker: the library's floats."""
    settings.max_active_jobs_per_token = 100  # every example (24) queued at once by one student
    settings.max_queued_per_token = 100  # (20 waiting: passed only while the worker took them fast enough)
    from tests.support.scene import EXAMPLES, small
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    scenes = {p.stem: small(json.loads(p.read_text()), 24, 18) for p in EXAMPLES}
    jobs = {name: submit(client, scene)["id"] for name, scene in scenes.items()}
    for name, job_id in jobs.items():
        ended = wait_finished(client, job_id, timeout=120)
        assert ended["status"] == "done", (name, ended["error"])
        p = ended["progress"]
        assert p["samples_done"] == p["samples_total"] > 0 and p["fraction"] == 1.0, (name, p)
        expected = render(compile_scene(load_scene(scenes[name])[0])).image
        np.testing.assert_array_equal(exr_of(client, job_id), expected, err_msg=name)


def test_api_jobs_raytree_is_a_worker_job_that_matches_the_library(client):
    from tracer.rendering.raytree import ray_tree
    from tracer.scene import load_scene

    scene = small(scene_dict("whitted"), 32, 24)
    r = client.post("/api/raytree", json={"scene": scene, "x": 21, "y": 13, "sample": 2})
    assert r.status_code == 200, r.text
    assert r.json() == json.loads(json.dumps(ray_tree(load_scene(scene)[0], 21, 13, 2)))
    bad = client.post("/api/raytree", json={"scene": scene, "x": 99, "y": 0})
    assert bad.status_code == 422
    assert bad.json()["errors"][0]["path"] == "x"
    missing = client.post("/api/raytree", json={"scene": scene})
    assert missing.status_code == 422
    assert {e["path"] for e in missing.json()["errors"]} == {"x", "y"}
