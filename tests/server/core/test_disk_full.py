"""A full disk (issue #15, item 6), on a small tmpfs that the test mounts as the data directory (the
tests run as root; a mount that cannot be made fails the test, it is never skipped) and fills with a file
of its own, then removes to give the space back.

- The API: every request that would write (a job, a ray tree, a class uploaded or posted, a scene to
  grade) is 507 with a message, and leaves nothing behind: no job row, no run folder, no upload.
- The embedded worker: the job it renders fails with the reason, recorded as soon as the store can be
  written; the worker itself lives on (same pid, never restarted), and takes new jobs once there is space.
- The Redis backend's API side: 507 too, and the events of a worker host wait (unacknowledged) until
  they can be applied, so the job still ends done once there is space."""

from __future__ import annotations

import base64
import json

from tests.support.api import Server, job, long_scene, submit, tiny_scene, wait_finished, wait_for
from tests.support.disk import fill_up, filled, is_507, tmpfs
from tests.support.grading_upload import assignment_text, class_zip
from tests.support.queue import Api, Process, RedisServer, proc_env, worker_argv


def test_disk_full_the_api_answers_507_and_keeps_nothing(tmp_path):
    with tmpfs(tmp_path / "data") as disk, Server(disk, workers=1) as server:
        http = server.client
        first = submit(http, tiny_scene())
        assert wait_finished(http, first["id"], timeout=120)["status"] == "done"
        assignment = json.loads(assignment_text())
        with filled(disk):
            is_507(http.post("/api/jobs", json={"scene": tiny_scene(seed=1)}))
            is_507(http.post("/api/raytree", json={"scene": tiny_scene(), "x": 1, "y": 1}))
            is_507(http.post("/api/grade/upload", data={"assignment": json.dumps(assignment)},
                             files={"class": ("hw4.zip", class_zip(), "application/zip")}))  # fmt: skip
            is_507(
                http.post("/api/grade", json={"assignment": assignment, "zip": base64.b64encode(class_zip()).decode()})
            )
            is_507(http.post("/api/grade", json={"assignment": assignment, "scene": tiny_scene()}))
            # reading goes on, and nothing of the refused requests is there
            listed = http.get("/api/jobs", params={"kind": "raytree"}).json()["count"], http.get("/api/jobs").json()
            assert listed[0] == 0 and listed[1]["count"] == 1, listed
            assert http.get("/api/health").json()["status"] == "ok"
            grades = disk / "grades"
            assert [p.name for p in grades.iterdir()] in ([], [".uploads"]), list(grades.iterdir())
            assert not (grades / ".uploads").exists() or not list((grades / ".uploads").iterdir())
        # space again: the same server takes jobs again
        again = submit(http, tiny_scene(seed=2))
        assert wait_finished(http, again["id"], timeout=120)["status"] == "done"


def test_disk_full_a_rendering_worker_fails_its_job_and_lives_on(tmp_path):
    """The worker used to die on "database or disk is full" with its job left running; the supervisor then
    retried the job on a new worker."""
    env = {"TRACER_PREVIEW_INTERVAL": "0.2"}  # a preview to write every 0.2 s: the disk is met soon
    with tmpfs(tmp_path / "data") as disk, Server(disk, workers=1, env=env) as server:
        http = server.client
        running = submit(http, long_scene(spp=4096))
        wait_for(lambda: job(http, running["id"])["preview"] >= 1, 120, "the job to render a pass")
        (pid,) = server.worker_pids()
        with filled(disk):
            wait_for(lambda: "disk is full" in server.log_text(), 60, "the worker to meet the full disk")
            assert server.worker_pids() == [pid]
        ended = wait_finished(http, running["id"], timeout=60)
        assert ended["status"] == "failed" and "the disk is full" in ended["error"], ended
        assert ended["attempts"] == 1  # failed with its reason, not retried as if its worker had crashed
        (worker,) = http.get("/api/health").json()["workers"]
        assert (worker["pid"], worker["alive"], worker["restarts"]) == (pid, True, 0)
        after = submit(http, tiny_scene(seed=3))
        assert wait_finished(http, after["id"], timeout=120)["status"] == "done"
    assert "Traceback" not in server.log_text()


def test_disk_full_redis_api_answers_507_and_applies_events_once_there_is_space(tmp_path):
    with (
        tmpfs(tmp_path / "data") as disk,
        RedisServer(tmp_path / "redis.log") as redis_server,
    ):
        api = Api(disk, redis_server.url, env=proc_env(TRACER_PREVIEW_INTERVAL="0.2")).start()
        host = Process(worker_argv(redis_server.url, "host-a"), tmp_path / "host-a.log").start()
        try:
            api.wait_hosts(1)
            running = api.submit(long_scene(spp=1024))
            api.wait(running["id"], lambda j: j["preview"] >= 1, "a pass")
            with filled(disk) as fill:
                # the running job's files are replaced as its passes arrive (every 0.2 s), and a replaced one gives
                # its space back: take that too, right before the request that must find no room; a 202 means a
                # replacement gave room back in between (the job was kept, rightly), so fill and ask again
                for _ in range(5):
                    fill_up(fill)
                    r = api.client.post("/api/jobs", json={"scene": tiny_scene()})
                    if r.status_code != 202:
                        break
                is_507(r)
                wait_for(lambda: "event waits to be applied" in api.log(), 120, "an event the API cannot apply")
            done = api.wait(running["id"], lambda j: j["finished"], "the job to end", timeout=300)
            assert done["status"] == "done" and done["progress"]["spp_done"] == 1024, done
            assert api.client.get(f"/api/jobs/{running['id']}/image").status_code == 200
            assert api.submit(tiny_scene())["status"] == "queued"
        finally:
            host.stop()
            api.stop()
