"""The Redis backend across hosts: network namespaces made by the test (tests/hosts.py). The broker
namespace holds Redis and the API; two worker namespaces join it over veth pairs and a bridge. Every
client (curl) runs inside a namespace; nothing is ever sent to a namespace's address from here.

- A worker host dies whole (every process in its namespace, its work horse in a session of its own
  included) in the middle of a job: the job runs again on the other host (attempts 2), continuing from
  the last snapshot of its film that reached the API, with the CLI's pixels.
- A host's cable is pulled mid-job and put back: the job runs again elsewhere, and what the cut-off
  try sends once it is back is dropped (counted, not applied): no stale or duplicate writes.
- A cancel reaches a job on whichever host runs it.

The API listens on the broker's address, not on loopback: its jobs are their tokens' (server/core/security.py),
so the requests here carry a student's token; and a request naming another host is refused (DNS rebinding).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.support.api import bearer, student_token, wait_for
from tests.support.hosts import Cluster
from tests.support.queue import LOST_AFTER, api_argv, proc_env, redis_argv, worker_argv
from tests.support.scene import ROOT, scene_dict, small
from tracer.rendering.film import read_exr

PORT = 8000


class Hosts:
    """The cluster with its services: Redis and the API in the broker, a worker host in each worker."""

    def __init__(self, cluster: Cluster, root):
        self.c, self.root = cluster, root
        self.redis_url = f"redis://{cluster.broker_ip}:6379/0"
        self.api = f"http://{cluster.broker_ip}:{PORT}"
        self.host_procs: dict[str, subprocess.Popen] = {}
        self.token = bearer(student_token())  # the jobs here are this student's

    def start(self) -> Hosts:
        c = self.c
        c.popen(c.broker, redis_argv(6379, bind=c.broker_ip), log=self.root / "redis.log")
        wait_for(
            lambda: c.run(c.broker, ["redis-cli", "-h", c.broker_ip, "ping"]).stdout.strip() == "PONG", 30, "Redis"
        )
        argv = api_argv(self.root / "data", PORT, self.redis_url, host=c.broker_ip)
        c.popen(c.broker, argv, log=self.root / "api.log", env=proc_env(), cwd=ROOT)
        wait_for(self._api_up, 120, "the API in the broker namespace", interval=0.3)
        for ns in c.workers:
            self.start_host(ns)
        wait_for(lambda: len(self.health()["workers"]) == len(c.workers), 120, "both worker hosts", interval=0.3)
        return self

    def start_host(self, ns: str) -> None:
        log = self.root / f"{ns}.log"
        self.host_procs[ns] = self.c.popen(
            ns, worker_argv(self.redis_url, self.name(ns)), log=log, env=proc_env(), cwd=ROOT
        )

    def name(self, ns: str) -> str:
        return f"host-{ns[-2:]}"  # w1 -> host-w1

    def ns_of(self, worker_name: str) -> str:
        return next(ns for ns in self.c.workers if self.name(ns) == worker_name)

    def _api_up(self) -> bool:
        try:
            return self.health().get("backend") == "redis"
        except RuntimeError:
            return False

    def call(self, method: str, path: str, body: dict | None = None, ns: str | None = None) -> tuple[int, dict]:
        """An HTTP request to the API, made from inside a namespace (the broker's unless said)."""
        return self.c.http(ns or self.c.broker, method, self.api + path, body, headers=self.token)

    def health(self) -> dict:
        return self.call("GET", "/api/health")[1]

    def submit(self, scene: dict) -> dict:
        status, job = self.call("POST", "/api/jobs", {"scene": scene})
        assert status == 202, job
        return job

    def job(self, job_id: str) -> dict:
        status, job = self.call("GET", f"/api/jobs/{job_id}")
        assert status == 200, job
        return job

    def wait(self, job_id: str, condition, what: str, timeout: float = 120) -> dict:
        return wait_for(lambda: condition(j := self.job(job_id)) and j, timeout, what, interval=0.2)

    def exr(self, job_id: str, path) -> np.ndarray:
        url = f"{self.api}/api/jobs/{job_id}/image?format=exr"
        assert self.c.fetch(self.c.broker, url, path, headers=self.token) == 200
        return read_exr(path)

    def logs(self) -> str:
        return "\n".join(
            f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}" for p in sorted(self.root.glob("*.log"))
        )


@pytest.fixture(scope="module")
def hosts(tmp_path_factory):
    root = tmp_path_factory.mktemp("hosts")
    with Cluster(workers=2) as cluster:
        h = Hosts(cluster, root)
        try:
            yield h.start()
        except BaseException:
            print(h.logs())
            raise


def job_scene(spp: int = 1024) -> dict:
    """Whitted's scene at 128 x 96: several seconds on one thread, many passes."""
    return small(scene_dict("whitted"), 128, 96, sampler={"type": "jittered", "spp": spp}, render={"seed": 5})


def cli_exr(scene: dict, tmp_path) -> np.ndarray:
    src, png, out = tmp_path / "scene.json", tmp_path / "cli.png", tmp_path / "cli.exr"
    src.write_text(json.dumps(scene))
    cmd = [sys.executable, "-m", "tracer", "render", str(src), "-o", str(png), "--exr", str(out)]
    subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, timeout=300)
    return read_exr(out)


def running_on(h: Hosts, job_id: str) -> dict:
    """Wait until the job runs and has shown an image; the job."""
    return h.wait(job_id, lambda j: j["status"] == "running" and j["preview"] >= 1, "the job to show a pass")


def test_queue_hosts_a_dead_host_s_job_finishes_on_the_other_with_the_cli_s_pixels(hosts, tmp_path):
    h = hosts
    scene = job_scene()
    job = h.submit(scene)
    first = h.wait(job["id"], lambda j: j["status"] == "running" and j["snapshot"] >= 2, "a snapshot of pass 2")
    victim = h.ns_of(first["tries"][-1]["worker"])
    killed = h.c.kill_host(victim)  # the whole host: worker, work horse (its own session), everything
    assert len(killed) >= 2, f"expected the worker and its work horse, killed {killed}"
    done = h.wait(job["id"], lambda j: j["finished"], "the job to finish on the other host", timeout=180)
    assert done["status"] == "done", (done, h.logs())
    assert done["attempts"] == 2
    lost, again = done["tries"]
    assert (lost["attempt"], lost["worker"], lost["outcome"]) == (1, h.name(victim), "lost")
    assert again["attempt"] == 2 and again["worker"] != h.name(victim) and again["outcome"] == "done"
    assert again["resumed_from"] >= first["snapshot"]  # it continued from the last pass that reached the API
    assert np.array_equal(h.exr(job["id"], tmp_path / "api.exr"), cli_exr(scene, tmp_path))
    h.start_host(victim)  # the host comes back for the next tests
    wait_for(lambda: len(h.health()["workers"]) == 2, 120, "the host to come back", interval=0.3)


def test_queue_hosts_a_cut_off_host_comes_back_and_writes_nothing(hosts, tmp_path):
    h = hosts
    job = h.submit(job_scene())
    first = running_on(h, job["id"])
    victim = h.ns_of(first["tries"][-1]["worker"])
    h.c.cut(victim)
    try:
        done = h.wait(job["id"], lambda j: j["finished"], "the job to finish on the other host", timeout=180)
        assert done["status"] == "done" and done["attempts"] == 2, (done, h.logs())
        assert [t["outcome"] for t in done["tries"]] == ["lost", "done"]
        image = h.exr(job["id"], tmp_path / "before.exr")
        stale_before = h.health()["queue"]["stale"]
    finally:
        h.c.restore(victim)
    # the cut-off try renders on and reports when it can: every report of it is dropped
    wait_for(lambda: h.health()["queue"]["stale"] > stale_before, 120, "the cut-off try's late reports", interval=0.3)
    time.sleep(2 * LOST_AFTER)  # more of them may follow: none may land
    after = h.job(job["id"])
    assert {k: after[k] for k in ("status", "attempts", "tries", "preview", "progress", "rays")} == {
        k: done[k] for k in ("status", "attempts", "tries", "preview", "progress", "rays")
    }
    assert np.array_equal(h.exr(job["id"], tmp_path / "after.exr"), image)
    # the cut-off host first renders its stale try to the end (seconds here; minutes on a loaded machine)
    wait_for(lambda: len(h.health()["workers"]) == 2, 240, f"the host to take work again: {h.health()}", interval=0.3)


def test_queue_hosts_cancel_reaches_a_job_on_another_host(hosts):
    h = hosts
    job = h.submit(job_scene(spp=4096))
    first = running_on(h, job["id"])
    host = h.ns_of(first["tries"][-1]["worker"])
    status, _ = h.call(
        "DELETE", f"/api/jobs/{job['id']}", ns=h.c.workers[0] if host != h.c.workers[0] else h.c.workers[1]
    )
    assert status == 202
    ended = h.wait(job["id"], lambda j: j["finished"], "the cancel to reach the host", timeout=30)
    assert ended["status"] == "cancelled"
    assert ended["tries"][-1]["outcome"] == "cancelled"
    assert ended["preview"] >= 1  # the last full pass is kept
    wait_for(lambda: all(w["job"] is None for w in h.health()["workers"]), 30, "the host to be free again")


def test_queue_hosts_jobs_are_their_token_s_and_the_host_is_checked(hosts):
    """An API on a network address, without an instructor token: another host's request without the job's
    token gets the 404 of an unknown id, grading is refused (there is no instructor), and a request that
    names a host the API does not serve is refused (400)."""
    h = hosts
    job = h.submit(small(scene_dict("whitted"), 16, 12, sampler={"type": "jittered", "spp": 1}))
    done = h.wait(job["id"], lambda j: j["finished"], "the small job")
    assert done["status"] == "done"
    other = h.c.workers[0]
    url = f"{h.api}/api/jobs/{job['id']}"
    status, body = h.c.http(other, "GET", url)
    assert status == 404
    assert body == {"errors": [{"path": "id", "message": f"no job with id '{job['id']}'"}]}
    status, body = h.c.http(other, "GET", url, headers=bearer(student_token()))
    assert status == 404
    assert h.c.http(other, "GET", f"{h.api}/api/jobs")[1] == {"jobs": [], "count": 0}
    assert h.call("GET", "/api/jobs", ns=other)[1]["count"] >= 1  # the job's own token, from any host
    status, body = h.c.http(other, "GET", f"{h.api}/api/grade/schema")
    assert status == 403
    assert "TRACER_INSTRUCTOR_TOKEN" in body["errors"][0]["message"]
    status, body = h.c.http(other, "GET", f"{h.api}/api/health", headers={"Host": "attacker.example"})
    assert status == 400
    assert body["errors"][0]["path"] == "Host"
    assert "without TRACER_INSTRUCTOR_TOKEN" in (h.root / "api.log").read_text()  # warned at start-up
