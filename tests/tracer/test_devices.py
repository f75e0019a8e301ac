"""The device plumbing, tested on the CPU (docs/scale.md, "GPU worker hosts").

- The CUDA rule (the band is the whole image, one launch per pass, no thread pool), forced here on the
  CPU, gives the banded image bit for bit, for every integrator and the adaptive sampler.
- An unknown device is refused with one clear message: by the library, the CLI and a worker host.
- The device reaches each job's record: `cpu` from the embedded backend; a worker host's `--device`
  through Redis, from a host of the GPU hosts' worker class (each try in the host's own process, no fork).

What needs a GPU is not here as skipped tests: `python -m bench.gpu` on a machine with one."""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import tracer.rendering.progressive as render_module
from tests.support.api import job, submit, tiny_scene, wait_finished, wait_for
from tests.support.queue import LOST_AFTER, Api, Process, RedisServer
from tests.support.scene import ROOT, scene_dict, small
from tracer.kernels.compile import compile_scene
from tracer.kernels.parallel import DeviceError, check_device
from tracer.rendering.film import read_exr
from tracer.rendering.progressive import BAND_PIXELS, Renderer, band_size, pass_schedule, render
from tracer.scene import load_scene

NO_DEVICE = "warp has no device cuda:99 here; available: cpu"  # then ", cuda:0" on a machine with a GPU

SCENES = {
    "whitted": small(scene_dict("whitted"), 40, 30, sampler={"type": "random", "spp": 5}),
    "path": small(scene_dict("cornell_path"), 24, 24, sampler={"type": "jittered", "spp": 4}),
    "adaptive": small(scene_dict("antialias_adaptive"), 24, 18),
    "radiosity": small(scene_dict("cornell_radiosity"), 24, 24, sampler={"type": "jittered", "spp": 1}),
}


def assert_same(a, b) -> None:
    """Two renders agree bit for bit: the image, the rays by kind and every AOV."""
    assert np.array_equal(a.image, b.image)
    assert a.rays == b.rays
    assert a.spp == b.spp
    assert a.aovs.keys() == b.aovs.keys()
    for name in a.aovs:
        assert np.array_equal(a.aovs[name], b.aovs[name]), name


# -- whole images: the CUDA rule, on the CPU ------------------------------------------------------


@pytest.mark.parametrize("name", SCENES)
def test_devices_whole_image_launches_give_the_banded_image_bit_for_bit(name):
    scene, _ = load_scene(SCENES[name])
    banded = render(compile_scene(scene), threads=2)
    bands = []

    def progress(p) -> None:
        if p.phase == "render":
            bands.append(p.samples_done)

    whole = render(compile_scene(scene), threads=2, band=None, progress=progress)
    assert_same(whole, banded)
    # one launch per pass, each the whole image
    d = scene.film.width * scene.film.height
    if scene.sampler.type == "adaptive":
        per_pass = [d] * (scene.sampler.max_level + 1)
    else:
        per_pass = [d * (s1 - s0) for s0, s1 in pass_schedule(scene.sampler.spp)]
    assert bands == list(np.cumsum(per_pass))


def test_devices_a_cuda_device_gets_whole_images_from_one_thread(monkeypatch):
    """band AUTO on a device that says it is CUDA (forced here): no pool, one band the size of the image,
    progress only once each launch has finished (the synchronise before it runs on the CPU too)."""
    scene, _ = load_scene(SCENES["whitted"])
    banded = render(compile_scene(scene), threads=2)
    monkeypatch.setattr(render_module, "is_cuda", lambda device: True)
    cs = compile_scene(scene)
    r = Renderer(cs, threads=4)
    assert (r.threads, r.band, len(r.stacks)) == (1, 40 * 30, 1)
    assert_same(render(cs, threads=4), banded)


def test_devices_the_cpu_keeps_its_bands():
    assert band_size("cpu", 256 * 256, 5, 0) == BAND_PIXELS
    assert band_size("cpu", 1000, 5, 0) == 1000
    assert band_size("cpu", 256 * 256, 5, 0, band=512) == 512
    # the adaptive sampler's cache of traced points stays within ADAPTIVE_CACHE_BYTES per thread
    points = (2**4 + 1) ** 2
    assert band_size("cpu", 256 * 256, 5, points) * points * 16 <= render_module.ADAPTIVE_CACHE_BYTES
    scene, _ = load_scene(SCENES["whitted"])
    r = Renderer(compile_scene(scene), threads=3)
    assert (r.threads, r.band) == (3, 40 * 30)


def test_devices_whole_images_are_cut_only_when_their_scratch_would_not_fit(monkeypatch):
    """A whole-image launch's ray stacks and adaptive cache stay within WHOLE_IMAGE_SCRATCH_BYTES: a bigger
    image goes in the fewest equal bands that fit, one after the other, with the same pixels."""
    budget = render_module.WHOLE_IMAGE_SCRATCH_BYTES
    assert band_size("cpu", 2048 * 2048, 5, 0, band=None) == 2048 * 2048  # the largest film, default depth: one
    assert band_size("cpu", 2048 * 2048, 10, 0, band=None) == 2048 * 2048 // 2  # deeper: two launches
    per_pixel = 65 * render_module.STACK_BYTES_PER_LEVEL + 513**2 * render_module.CACHE_BYTES_PER_POINT
    band = band_size("cpu", 2048 * 2048, 64, 513**2, band=None)  # the deepest adaptive render
    assert band * per_pixel <= budget
    assert (band + 1) * per_pixel > budget // 2
    scene, _ = load_scene(SCENES["whitted"])
    banded = render(compile_scene(scene), threads=2)
    per_pixel = (scene.render.max_depth + 1) * render_module.STACK_BYTES_PER_LEVEL
    monkeypatch.setattr(render_module, "WHOLE_IMAGE_SCRATCH_BYTES", 130 * per_pixel)
    cs = compile_scene(scene)
    r = Renderer(cs, band=None)
    assert r.band == 120
    assert r.threads == 1  # 1200 pixels: 10 bands of 120 (not 9 of 130 and one of 30)
    assert_same(render(cs, band=None), banded)


def test_devices_a_snapshot_resumes_across_band_rules():
    """A render stopped on one device kind's rule resumes on the other's: the same sums, bit for bit."""
    scene, _ = load_scene(SCENES["path"])
    cs = compile_scene(scene)
    whole = render(cs, threads=2)
    first = Renderer(cs, threads=2)
    first.add_samples(0, 2)
    later = Renderer(cs, band=None)
    later.restore(first.snapshot())
    later.add_samples(2, 4)
    assert np.array_equal(later.image(), whole.image) and later.rays() == whole.rays


def test_devices_a_scene_compiled_for_another_device_is_refused():
    """The scene's arrays must live on the device that renders it (stood for here by a scene whose
    arrays say cuda:0): a clear error, not Warp's about a launch's inputs."""
    elsewhere = SimpleNamespace(data=SimpleNamespace(shapes=SimpleNamespace(device="cuda:0")))
    with pytest.raises(ValueError, match=r"compiled for cuda:0, not cpu: compile_scene\(scene, device='cpu'\)"):
        Renderer(elsewhere, device="cpu")


# -- unknown devices ------------------------------------------------------------------------------


def test_devices_names_are_checked():
    assert check_device("cpu") == "cpu" and check_device(" cpu ") == "cpu" and check_device(None) == "cpu"
    for name in ("cuda:99", "gpu"):
        with pytest.raises(DeviceError) as e:
            check_device(name)
        assert str(e.value).startswith(f"warp has no device {name} here; available: cpu")


def test_devices_the_cli_renders_on_the_cpu_and_refuses_an_unknown_device(tmp_path):
    src, png, exr = tmp_path / "scene.json", tmp_path / "out.png", tmp_path / "out.exr"
    src.write_text(json.dumps(SCENES["whitted"]))
    cmd = [sys.executable, "-m", "tracer", "render", str(src), "-o", str(png), "--exr", str(exr)]
    p = subprocess.run([*cmd, "--device", "cpu"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert " on " not in p.stdout  # the device is named only when it is not the CPU
    scene, _ = load_scene(SCENES["whitted"])
    assert np.array_equal(read_exr(exr), render(scene).image)
    p = subprocess.run([*cmd, "--device", "cuda:99"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and NO_DEVICE in p.stderr, p.stderr
    assert "Warp" not in p.stderr
    assert p.stdout == ""  # no driver noise, no greeting


def test_devices_a_worker_host_refuses_an_unknown_device_before_it_connects():
    cmd = [sys.executable, "-m", "server.worker", "--redis", "redis://127.0.0.1:9/0", "--device", "cuda:99"]
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and NO_DEVICE in p.stderr, p.stderr


# -- the device in the job's record ---------------------------------------------------------------


def test_devices_the_embedded_backend_records_the_cpu(client):
    created = submit(client, tiny_scene(8, spp=1))
    done = wait_finished(client, created["id"])
    assert done["status"] == "done"
    assert done["device"] == "cpu"
    assert [t["device"] for t in done["tries"]] == ["cpu"]
    workers = client.get("/api/health").json()["workers"]
    assert workers
    assert {w["device"] for w in workers} == {"cpu"}
    assert job(client, created["id"])["device"] == "cpu"


def test_devices_a_gpu_hosts_worker_class_on_the_cpu(tmp_path):
    """A worker host started with `--device cpu --no-fork` runs each try in its own process, as a CUDA
    host does: its device reaches /api/health and the job's record; its pixels are the library's; a try
    longer than the loss timeout is not lost (its heartbeats come from a thread); a SIGTERM gives the
    try back and the host exits cleanly."""
    with RedisServer(tmp_path / "redis.log") as redis_server:
        api = Api(tmp_path / "data", redis_server.url).start()
        argv = [sys.executable, "-m", "server.worker", "--redis", redis_server.url, "--name", "gpu-like"]
        host = Process([*argv, "--device", "cpu", "--no-fork", "--threads", "1"], tmp_path / "host.log").start()
        try:
            api.wait_hosts(1)
            # RQ registers a host a moment before its first heartbeat describes it (device, threads)
            (worker,) = wait_for(lambda: (w := api.health()["workers"])[0]["device"] and w, 30, "the host's device")
            assert (worker["name"], worker["device"], worker["threads"]) == ("gpu-like", "cpu", 1)
            scene = small(scene_dict("whitted"), 48, 36, sampler={"type": "jittered", "spp": 16}, render={"seed": 5})
            done = api.wait(api.submit(scene)["id"], lambda j: j["finished"], "a job on the in-process host")
            assert done["status"] == "done" and done["device"] == "cpu", done
            (one,) = done["tries"]
            assert (one["device"], one["worker"], one["outcome"]) == ("cpu", "gpu-like", "done")
            r = api.client.get(f"/api/jobs/{done['id']}/image", params={"format": "exr"})
            (tmp_path / "api.exr").write_bytes(r.content)
            parsed, _ = load_scene(scene)
            assert np.array_equal(read_exr(tmp_path / "api.exr"), render(parsed, threads=2).image)
            assert "tries in this process" in host.log()

            # minutes on one thread: SIGTERM comes long before its end
            long = api.submit(small(scene_dict("whitted"), 384, 288, sampler={"type": "jittered", "spp": 4096}))
            running = api.wait(
                long["id"],
                lambda j: j["attempts"] > 1 or (j["status"] == "running" and j["elapsed"] > 2.5 * LOST_AFTER),
                "a long try",
            )
            # one try all along: without its heartbeats it would be lost every LOST_AFTER seconds
            assert running["attempts"] == 1 and len(running["tries"]) == 1, running["tries"]
            assert api.health()["queue"]["lost"] == 0
            host.proc.send_signal(signal.SIGTERM)
            # the try stops at its next launch (a second or so); the bound only catches a host that hangs (a
            # CI machine under load once took more than a minute here: its log says where the time went)
            try:
                code = host.proc.wait(timeout=180)
            except subprocess.TimeoutExpired:
                host.proc.send_signal(signal.SIGUSR2)  # faulthandler: every thread's stack into its log
                with contextlib.suppress(subprocess.TimeoutExpired):
                    host.proc.wait(timeout=2)
                pytest.fail(f"the host did not exit within 180 s of its SIGTERM; its log:\n{host.log()}")
            assert code == 0, host.log()
            back = api.wait(long["id"], lambda j: j["status"] == "queued", "the try given back")
            assert back["tries"][0]["outcome"] == "given back"
            assert back["tries"][0]["device"] == "cpu"
            assert api.client.delete(f"/api/jobs/{long['id']}").status_code == 200
        finally:
            host.stop()
            api.stop()
