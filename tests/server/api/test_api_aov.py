"""The page's additions to the jobs API: AOV pictures of a finished job, the job's scene, rays in progress events."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from server.jobs.files import AOV_NAMES
from tests.support.api import long_scene, parse_sse, submit, tiny_scene, wait_for, wait_status
from tests.support.scene import ROOT


def test_api_aov_pictures_of_a_finished_job(client, compiled_kernels):
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    scene = tiny_scene(24, spp=4, seed=3)
    scene["film"]["height"] = 18
    job_id = submit(client, scene)["id"]
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
    job_id = submit(client, long_scene())["id"]
    wait_status(client, job_id, {"running"})
    r = client.get(f"/api/jobs/{job_id}/aov/rays")
    assert r.status_code == 404
    assert "saved when the job is done" in r.json()["errors"][0]["message"]
    assert client.get(f"/api/jobs/{job_id}/aov").status_code == 404
    client.delete(f"/api/jobs/{job_id}")
    wait_status(client, job_id, {"cancelled"})
    assert client.get(f"/api/jobs/{job_id}/aov/depth").status_code == 404  # a cancelled job keeps no AOVs
    done = submit(client, tiny_scene())["id"]
    wait_status(client, done, {"done"})
    r = client.get(f"/api/jobs/{done}/aov/colour")
    assert r.status_code == 404
    assert r.json()["errors"][0]["path"] == "name"
    assert "one of: rays, depth" in r.json()["errors"][0]["message"]
    assert client.get("/api/jobs/AAAAAAAAAAAAAAAAAAAAAA/aov/rays").status_code == 404


def test_api_aov_job_scene_and_rays_in_progress_events(client):
    scene = tiny_scene(16, spp=4, seed=11)
    job_id = submit(client, scene)["id"]
    assert client.get(f"/api/jobs/{job_id}/scene").json() == scene
    wait_status(client, job_id, {"done"})
    with client.stream("GET", f"/api/jobs/{job_id}/events") as r:
        events = list(parse_sse(r.iter_lines()))
    progress = [d for e, d in events if e == "progress"]
    assert progress
    assert progress[-1]["rays"]["eye"] == 16 * 16 * 4
    assert client.get("/api/jobs/AAAAAAAAAAAAAAAAAAAAAA/scene").status_code == 404


def test_api_radiosity_solution_of_a_finished_job(client):
    """A radiosity job keeps its solution: the patches, the energy balance, who shot when."""
    import json

    scene = json.loads((ROOT / "scenes" / "cornell_radiosity.json").read_text())
    scene["film"].update(width=16, height=16)
    scene["sampler"] = {"type": "center"}
    scene["render"]["radiosity"] = {"patch_size": 0.5, "rays": 256, "threshold": 0.05}
    job_id = submit(client, scene)["id"]
    wait_status(client, job_id, {"done"}, timeout=120)
    sol = client.get(f"/api/jobs/{job_id}/radiosity").json()
    n = len(sol["patches"]["area"])
    assert n > 0
    assert len(sol["radiosity"]) == n
    assert len(sol["patches"]["corner"]) == n
    e = sol["energy"]
    balance = np.array(e["emitted"]) - np.array(e["absorbed"]) - np.array(e["unshot"]) - np.array(e["escaped"])
    np.testing.assert_allclose(balance, 0, atol=1e-4 * max(e["emitted"]))
    assert sol["history"][0]["shooter"] == "lights[0]"
    assert isinstance(sol["history"][1]["shooter"], int)
    assert "1" in sol["snapshots"]
    assert len(sol["snapshots"]["1"]) == n
    # a job of another integrator has none
    other = submit(client, tiny_scene(8, spp=1, seed=1))["id"]
    wait_status(client, other, {"done"})
    r = client.get(f"/api/jobs/{other}/radiosity")
    assert r.status_code == 404
    assert "not radiosity" in r.json()["errors"][0]["message"]


def test_api_radiosity_solve_is_a_phase_with_progress_stats_and_cancel(client):
    """The solve reports its own progress (phase 'radiosity', the solve's fraction and shots) before the
    first pass, ends in the job's stats (shots, patches, the solve's rays), and a cancel stops it mid-solve."""
    import json

    scene = json.loads((ROOT / "scenes" / "cornell_spheres_radiosity.json").read_text())
    scene["film"].update(width=16, height=16)
    scene["sampler"] = {"type": "center"}
    scene["render"]["radiosity"] = {"patch_size": 0.25, "rays": 1024, "threshold": 0.002, "max_steps": 20000}
    job_id = submit(client, scene)["id"]
    events = []
    with client.stream("GET", f"/api/jobs/{job_id}/events") as r:
        for event, data in parse_sse(r.iter_lines()):
            events.append((event, data))
            if event == "end":
                break
    progress = [d for e, d in events if e == "progress"]
    solving = [d for d in progress if d["phase"] == "radiosity"]
    assert len(solving) >= 2, "the solve reported no progress of its own"
    assert all(d["solve"]["shots"] > 0 and 0 <= d["solve"]["fraction"] < 1 and d["samples_done"] == 0 for d in solving)
    assert [d["solve"]["shots"] for d in solving] == sorted(d["solve"]["shots"] for d in solving)
    done = events[-1][1]
    assert done["status"] == "done"
    assert done["progress"]["phase"] == "finished"
    solve = done["progress"]["solve"]
    assert solve["fraction"] == 1
    assert solve["shots"] > len(solving)
    assert solve["patches"] > 0
    assert done["rays"]["radiosity"] == solve["rays"] > 0
    assert done["rays"]["total"] == sum(v for k, v in done["rays"].items() if k != "total")
    # cancelled while it solves (a solve of minutes): the job ends long before the solve would, with no pass
    scene["render"]["radiosity"].update(patch_size=0.1, rays=4096, threshold=1e-6)
    job_id = submit(client, scene)["id"]
    wait_for(lambda: client.get(f"/api/jobs/{job_id}").json()["progress"]["phase"] == "radiosity", 60, "the solve")
    assert client.delete(f"/api/jobs/{job_id}").status_code in (200, 202)
    ended = wait_status(client, job_id, {"cancelled"}, timeout=10)
    assert ended["progress"]["passes_done"] == 0
    assert ended["preview"] == 0


def test_api_aov_data_pictures_keep_their_values():
    """depth and normal are data, not radiance: written through png_bytes(srgb=False), each byte round(255 v)
    (depth as grey); albedo goes through the sRGB curve like the image."""
    from server.queue.outputs import aov_pictures
    from tracer.rendering.film import to_srgb8

    normal = np.array([[[1.0, 0.0, -1.0], [0.2, -0.6, 0.5]]], dtype=np.float32)  # (1, 2, 3)
    depth = np.array([[2.0, 0.0]], dtype=np.float32)  # one hit, one miss
    pictures, ranges = aov_pictures({"normal": normal, "depth": depth, "albedo": np.full((1, 2, 3), 0.5)})
    read = {name: np.asarray(Image.open(io.BytesIO(png))) for name, png in pictures.items()}
    np.testing.assert_array_equal(read["normal"], np.round((0.5 + 0.5 * normal) * 255).astype(np.uint8))
    assert read["depth"].tolist() == [[round(0.15 * 255), 0]]  # near white to far grey; black: no hit
    np.testing.assert_array_equal(read["albedo"], to_srgb8(np.full((1, 2, 3), 0.5)))
    assert ranges["depth"] == [2.0, 2.0]
    assert ranges["normal"] == [-1.0, 1.0]
