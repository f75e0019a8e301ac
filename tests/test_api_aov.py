"""The page's additions to the jobs API: AOV pictures of a finished job, the job's scene, rays in progress events."""

from __future__ import annotations

import io

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image
from test_api_support import long_scene, parse_sse, tiny_scene, wait_for

from server.main import create_app
from server.settings import Settings
from server.worker import AOV_NAMES


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    settings = Settings(data_dir=tmp_path_factory.mktemp("aov-data"), workers=1)
    with TestClient(create_app(settings)) as c:
        wait_for(lambda: all(w["ready"] for w in c.get("/api/health").json()["workers"]), 60, "the worker")
        yield c


def submit(client, scene: dict) -> str:
    r = client.post("/api/jobs", json={"scene": scene})
    assert r.status_code == 202, r.text
    return r.json()["id"]


def wait_status(client, job_id: str, statuses: set[str], timeout: float = 60) -> dict:
    return wait_for(
        lambda: (j := client.get(f"/api/jobs/{job_id}").json())["status"] in statuses and j, timeout, str(statuses)
    )


def test_api_aov_pictures_of_a_finished_job(client, compiled_kernels):
    from tracer.compile import compile_scene
    from tracer.render import render
    from tracer.scene import load_scene

    scene = tiny_scene(24, spp=4, seed=3)
    scene["film"]["height"] = 18
    job_id = submit(client, scene)
    wait_status(client, job_id, {"done"})
    listing = client.get(f"/api/jobs/{job_id}/aov").json()
    assert listing["names"] == list(AOV_NAMES)
    expected = render(compile_scene(load_scene(scene)[0])).aovs
    # the ranges are those of the library's AOVs (rays exactly: they are counts)
    assert listing["ranges"]["rays"] == [float(expected["rays"].min()), float(expected["rays"].max())]
    hit = expected["depth"][expected["depth"] > 0]
    np.testing.assert_allclose(listing["ranges"]["depth"], [hit.min(), hit.max()], rtol=1e-6)
    for name in AOV_NAMES:
        r = client.get(f"/api/jobs/{job_id}/aov/{name}")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png", name
        picture = np.asarray(Image.open(io.BytesIO(r.content)).convert("RGB"))
        assert picture.shape == (18, 24, 3), name
    # the rays heat map: white where the most rays were traced, black nowhere below the maximum's third
    rays = np.asarray(Image.open(io.BytesIO(client.get(f"/api/jobs/{job_id}/aov/rays").content)).convert("RGB"))
    top = expected["rays"] == expected["rays"].max()
    assert (rays[top] == 255).all()
    # the normal picture is 0.5 + 0.5 n, without the sRGB curve (tolerance: 8-bit rounding of an average)
    normal = np.asarray(Image.open(io.BytesIO(client.get(f"/api/jobs/{job_id}/aov/normal").content)).convert("RGB"))
    np.testing.assert_allclose(normal / 255.0, np.clip(0.5 + 0.5 * expected["normal"], 0, 1), atol=1 / 255 + 1e-6)


def test_api_aov_unknown_names_and_unfinished_jobs_are_404(client):
    job_id = submit(client, long_scene())
    wait_status(client, job_id, {"running"})
    r = client.get(f"/api/jobs/{job_id}/aov/rays")
    assert r.status_code == 404 and "saved when the job is done" in r.json()["errors"][0]["message"]
    assert client.get(f"/api/jobs/{job_id}/aov").status_code == 404
    client.delete(f"/api/jobs/{job_id}")
    wait_status(client, job_id, {"cancelled"})
    assert client.get(f"/api/jobs/{job_id}/aov/depth").status_code == 404  # a cancelled job keeps no AOVs
    done = submit(client, tiny_scene())
    wait_status(client, done, {"done"})
    r = client.get(f"/api/jobs/{done}/aov/colour")
    assert r.status_code == 404 and r.json()["errors"][0]["path"] == "name"
    assert "one of: rays, depth" in r.json()["errors"][0]["message"]
    assert client.get("/api/jobs/AAAAAAAAAAAAAAAAAAAAAA/aov/rays").status_code == 404


def test_api_aov_job_scene_and_rays_in_progress_events(client):
    scene = tiny_scene(16, spp=4, seed=11)
    job_id = submit(client, scene)
    assert client.get(f"/api/jobs/{job_id}/scene").json() == scene
    wait_status(client, job_id, {"done"})
    with client.stream("GET", f"/api/jobs/{job_id}/events") as r:
        events = list(parse_sse(r.iter_lines()))
    progress = [d for e, d in events if e == "progress"]
    assert progress and progress[-1]["rays"]["eye"] == 16 * 16 * 4
    assert client.get("/api/jobs/AAAAAAAAAAAAAAAAAAAAAA/scene").status_code == 404


def test_api_radiosity_solution_of_a_finished_job(client):
    """A radiosity job keeps its solution: the patches, the energy balance, who shot when."""
    import json
    from pathlib import Path

    scene = json.loads((Path(__file__).resolve().parent.parent / "scenes" / "cornell_radiosity.json").read_text())
    scene["film"].update(width=16, height=16)
    scene["sampler"] = {"type": "center"}
    scene["render"]["radiosity"] = {"patch_size": 0.5, "rays": 256, "threshold": 0.05}
    job_id = submit(client, scene)
    wait_status(client, job_id, {"done"}, timeout=120)
    sol = client.get(f"/api/jobs/{job_id}/radiosity").json()
    n = len(sol["patches"]["area"])
    assert n > 0 and len(sol["radiosity"]) == n and len(sol["patches"]["corner"]) == n
    e = sol["energy"]
    balance = np.array(e["emitted"]) - np.array(e["absorbed"]) - np.array(e["unshot"]) - np.array(e["escaped"])
    np.testing.assert_allclose(balance, 0, atol=1e-4 * max(e["emitted"]))
    assert sol["history"][0]["shooter"] == "lights[0]" and isinstance(sol["history"][1]["shooter"], int)
    assert "1" in sol["snapshots"] and len(sol["snapshots"]["1"]) == n
    # a job of another integrator has none
    other = submit(client, tiny_scene(8, spp=1, seed=1))
    wait_status(client, other, {"done"})
    r = client.get(f"/api/jobs/{other}/radiosity")
    assert r.status_code == 404 and "not radiosity" in r.json()["errors"][0]["message"]
