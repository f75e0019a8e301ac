"""The Redis backend on one host: a real redis-server on loopback, the API with `--redis`, worker hosts
as `python -m server.worker` processes. The same job life as the embedded backend's: submit, previews,
done with the CLI's pixels, cancel (running and queued), a restart of the API; and Redis losing its data."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from tests.support.api import long_scene, parse_sse, wait_for
from tests.support.queue import Api, Process, RedisServer, proc_env, worker_argv
from tests.support.scene import ROOT, scene_dict, small
from tracer.rendering.film import read_exr


@pytest.fixture(scope="module")
def redis_server(tmp_path_factory):
    with RedisServer(tmp_path_factory.mktemp("redis") / "redis.log") as r:
        yield r


@pytest.fixture(scope="module")
def cluster(redis_server, tmp_path_factory):
    """The API alone (workers 0) and one worker host of one thread, on loopback."""
    root = tmp_path_factory.mktemp("rq")
    api = Api(root / "data", redis_server.url).start()
    host = Process(worker_argv(redis_server.url, "host-a"), root / "host-a.log").start()
    try:
        api.wait_hosts(1)
        yield api, host, root
    finally:
        host.stop()
        api.stop()


def exr(api: Api, job_id: str, path) -> np.ndarray:
    r = api.client.get(f"/api/jobs/{job_id}/image", params={"format": "exr"})
    assert r.status_code == 200
    assert r.headers["content-type"] == "image/x-exr"
    path.write_bytes(r.content)
    return read_exr(path)


def cli_exr(scene: dict, tmp_path) -> np.ndarray:
    """The same scene rendered by the command line."""
    import json

    src, png, out = tmp_path / "scene.json", tmp_path / "cli.png", tmp_path / "cli.exr"
    src.write_text(json.dumps(scene))
    cmd = [sys.executable, "-m", "tracer", "render", str(src), "-o", str(png), "--exr", str(out), "--threads", "2"]
    subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, timeout=300)
    return read_exr(out)


def test_queue_redis_job_life_previews_and_the_cli_s_pixels(cluster, tmp_path):
    api, host, _ = cluster
    health = api.health()
    assert health["backend"] == "redis"
    (worker,) = health["workers"]
    assert worker["name"] == "host-a"
    assert worker["device"] == "cpu"
    assert worker["threads"] == 1
    assert worker["host"]
    scene = small(scene_dict("whitted"), 96, 72, sampler={"type": "jittered", "spp": 64}, render={"seed": 3})
    job = api.submit(scene)
    events = []
    with api.client.stream("GET", f"/api/jobs/{job['id']}/events", timeout=120) as r:
        for event, data in parse_sse(r.iter_lines()):
            events.append((event, data))
            if event == "end":
                break
    kinds = [e for e, _ in events]
    assert kinds.count("preview") >= 2 and "progress" in kinds, kinds
    done = events[-1][1]
    assert done["status"] == "done"
    assert done["attempts"] == 1
    assert done["finished"]
    assert done["host"]
    assert done["device"] == "cpu"
    (one,) = done["tries"]
    assert (one["attempt"], one["worker"], one["outcome"]) == (1, "host-a", "done")
    assert done["rays"]["eye"] == 96 * 72 * 64
    assert done["progress"]["spp_done"] == 64
    # the same pixels as the command line, bit for bit, and the AOVs came along
    assert np.array_equal(exr(api, job["id"], tmp_path / "api.exr"), cli_exr(scene, tmp_path))
    assert api.client.get(f"/api/jobs/{job['id']}/aov/rays").status_code == 200
    assert api.client.get(f"/api/jobs/{job['id']}/image").headers["content-type"] == "image/png"


def test_queue_redis_cancel_a_running_and_a_queued_job(cluster):
    api, _, _ = cluster
    running = api.submit(long_scene())
    api.wait(running["id"], lambda j: j["status"] == "running" and j["progress"]["passes_done"] >= 1, "a pass")
    queued = api.submit(long_scene())  # the only host is busy: it waits in RQ
    assert api.job(queued["id"])["status"] == "queued"
    r = api.client.delete(f"/api/jobs/{queued['id']}")
    assert r.status_code == 200
    assert r.json()["status"] == "cancelled"
    r = api.client.delete(f"/api/jobs/{running['id']}")
    assert r.status_code == 202
    ended = api.wait(running["id"], lambda j: j["finished"], "the running job to stop", timeout=30)
    assert ended["status"] == "cancelled"
    assert ended["preview"] >= 1  # it keeps its last full pass
    assert ended["tries"][-1]["outcome"] == "cancelled"
    # the host is free again, and the cancelled queued job never ran
    after = api.submit(small(scene_dict("whitted"), 16, 16, sampler={"type": "jittered", "spp": 4}))
    assert api.wait(after["id"], lambda j: j["finished"], "a job after the cancels")["status"] == "done"
    assert api.job(queued["id"])["tries"] == []


def test_queue_redis_api_restart_loses_nothing(redis_server, tmp_path):
    """The API stops while a worker host renders; the host finishes meanwhile; the API, started again on
    the same data, applies what it missed: the job is done, its image there. (Database 1: one API per
    Redis database, and the module's cluster has database 0.)"""
    url = redis_server.url.replace("/0", "/1")
    api = Api(tmp_path / "data", url).start()
    host = Process(worker_argv(url, "host-r"), tmp_path / "host-r.log").start()
    try:
        api.wait_hosts(1)
        # about 2.5 s on one thread here: long enough to be seen running between two polls on any machine (at
        # 256 samples, 0.65 s, a loaded CI's polls once missed it and waited for a status that had come and gone)
        scene = small(scene_dict("whitted"), 64, 48, sampler={"type": "jittered", "spp": 1024})
        job = api.submit(scene)
        seen = api.wait(job["id"], lambda j: j["status"] == "running" or j["finished"], "the job to start")
        assert seen["status"] == "running", f"the job ended before it was seen running: {seen}"
        api.stop()
        redis = redis_server.client(1)
        key = f"rq:job:{job['id']}-try1"
        wait_for(lambda: redis.hget(key, "status") == b"finished", 120, "the host to finish while the API is down")
        api = Api(tmp_path / "data", url, port=api.port).start()
        done = api.wait(job["id"], lambda j: j["finished"], "the job to be done after the restart", timeout=30)
        assert done["status"] == "done"
        assert done["attempts"] == 1
        assert np.array_equal(exr(api, job["id"], tmp_path / "after.exr"), cli_exr(scene, tmp_path))
    finally:
        host.stop()
        api.stop()


def test_queue_redis_losing_its_data_requeues_what_the_store_has(redis_server, tmp_path):
    """Redis is flushed while jobs wait (no host yet): the API notices and queues them again (database 2)."""
    url = redis_server.url.replace("/0", "/2")
    api = Api(tmp_path / "data", url).start()
    host = None
    try:
        scene = small(scene_dict("whitted"), 16, 16, sampler={"type": "jittered", "spp": 4})
        jobs = [api.submit(scene) for _ in range(2)]
        redis = redis_server.client(2)
        assert redis.exists(f"rq:job:{jobs[0]['id']}-try1")
        redis.flushdb()
        wait_for(lambda: redis.exists(f"rq:job:{jobs[0]['id']}-try1"), 20, "the API to queue the jobs again")
        host = Process(worker_argv(url, "host-f"), tmp_path / "host-f.log", proc_env()).start()
        for j in jobs:
            assert api.wait(j["id"], lambda x: x["finished"], "a job after the flush")["status"] == "done"
    finally:
        if host is not None:
            host.stop()
        api.stop()


def test_queue_redis_grades_a_class_through_the_worker_hosts(cluster):
    """Grading needs nothing new: its renders are jobs like any other, rendered on a worker host, their
    images and variances back on the API host: the example's scores (the example class:
    tests/tracer/grading/test_grading.py)."""
    import base64
    import json

    from tests.support.grading import CLASS, EXAMPLE, assignment_dict

    api, _, _ = cluster
    assignment = assignment_dict()
    assignment["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    body = {
        "assignment": assignment,
        "submissions": [
            {"student": "erin", "scene": (CLASS / "erin.json").read_text()},
            {"student": "grace", "image": base64.b64encode((CLASS / "grace.png").read_bytes()).decode()},
        ],
    }
    r = api.client.post("/api/grade", json=body)
    assert r.status_code == 202, r.text
    url = r.json()["url"]
    state = wait_for(
        lambda: (s := api.client.get(url).json())["status"] != "running" and s, 300, "the grading run", 0.5
    )
    assert state["status"] == "done", state
    scores = {x["student"]: (x["score"], x["status"]) for x in state["reports"]}
    assert scores == {"erin": (7.0, "graded"), "grace": (7.0, "graded")}


def test_queue_redis_one_api_per_database(redis_server, cluster, tmp_path):
    """A second API on the database the first one uses would split its events: it refuses to start."""
    second = Process(
        [
            sys.executable,
            "-m",
            "server",
            "--port",
            "0",
            "--data-dir",
            str(tmp_path / "d2"),
            "--redis",
            redis_server.url,
        ],
        tmp_path / "second.log",
    ).start()
    try:
        wait_for(lambda: not second.alive(), 60, "the second API to give up")
        assert "another API uses this Redis database" in second.log()
    finally:
        second.stop()


def test_queue_redis_a_batch_render_gives_way_on_its_host_and_resumes(cluster, tmp_path):
    """The only host renders a batch job; an interactive one waits: the batch render stops at its next
    pass (its film sent to the API), the interactive job runs, and the batch render's next try continues
    from that film, on a host that has never seen it, to the CLI's image bit for bit."""
    api, _, _ = cluster
    scene = small(scene_dict("whitted"), 128, 96, sampler={"type": "jittered", "spp": 2304}, render={"seed": 11})
    r = api.client.post("/api/jobs", json={"scene": scene, "lane": "batch"})
    assert r.status_code == 202
    assert r.json()["lane"] == "batch"
    long = r.json()
    api.wait(long["id"], lambda j: j["progress"]["passes_done"] >= 3, "three passes")
    quick = api.submit(small(scene_dict("whitted"), 16, 12, sampler={"type": "jittered", "spp": 4}))
    assert api.wait(quick["id"], lambda j: j["finished"], "the interactive job")["status"] == "done"
    done = api.wait(long["id"], lambda j: j["finished"], "the batch job", timeout=180)
    assert done["status"] == "done"
    assert [t["outcome"] for t in done["tries"]] == ["gave way", "done"]
    assert done["tries"][1]["resumed_from"] >= 3
    assert np.array_equal(exr(api, long["id"], tmp_path / "api.exr"), cli_exr(scene, tmp_path))


def test_queue_redis_ray_trees_run_on_hosts_and_a_radiosity_solution_is_solved_once(cluster):
    api, _, _ = cluster
    scene = small(scene_dict("cornell_radiosity"), 32, 32, sampler={"type": "center", "spp": 1})
    scene["render"]["radiosity"].update(patch_size=0.5, rays=512, threshold=0.05)
    trees = []
    for x, y in ((10, 12), (20, 25)):
        r = api.client.post("/api/raytree", json={"scene": scene, "x": x, "y": y})
        assert r.status_code == 200, r.text
        trees.append(r.json())
    assert [t["pixel"] for t in trees] == [[10, 12], [20, 25]]
    jobs = api.client.get("/api/jobs", params={"kind": "raytree", "limit": 2}).json()["jobs"]
    second, first = jobs  # newest first
    assert first["progress"]["solve"]["cached"] is False
    assert second["progress"]["solve"]["cached"] is True
    assert first["host"]
    assert second["device"] == "cpu"
    assert all(j["id"] not in {x["id"] for x in api.client.get("/api/jobs").json()["jobs"]} for j in jobs)
