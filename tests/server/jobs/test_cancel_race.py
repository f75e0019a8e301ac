"""The cancel race (issue #15, item 8): submit a job, cancel it a moment later, many times, against a real
worker, on both backends. Whenever the cancel lands (the job queued, running, in its last band, or just
done), the answer the client got and the job's final status agree:

    200 -> cancelled (it was queued)    202 -> cancelled (it was running)    409 -> done (it had ended)

The jobs are short (a few passes of a small scene) so that many cancels land in a render's last pass,
after its last look at the cancel flag; the delays sweep that window. The store's own test of the race is
tests/server/jobs/test_store.py (test_store_an_accepted_cancel_wins_over_the_try_s_end)."""

from __future__ import annotations

import time

import pytest

from tests.support.api import submit, wait_finished, wait_for
from tests.support.queue import Api, Process, RedisServer, worker_argv
from tests.support.scene import scene_dict, small

TRIES = 30
AGREES = {200: {"cancelled"}, 202: {"cancelled"}, 409: {"done"}}


def race_scene(k: int) -> dict:
    """Whitted's scene at 64 x 64, 64 samples: six passes, tens of milliseconds of rendering."""
    return small(scene_dict("whitted"), 64, 64, sampler={"type": "jittered", "spp": 64}, render={"seed": k})


def render_seconds(http) -> float:
    """How long a job takes here from the submit's answer until it is seen done (polled every 5 ms)."""
    job = submit(http, race_scene(1000))
    start = time.monotonic()
    wait_for(lambda: http.get(f"/api/jobs/{job['id']}").json()["finished"], 120, "the calibration job", 0.005)
    return time.monotonic() - start


def submit_then_cancel(http, tries: int = TRIES) -> list[tuple[int, str, str]]:
    """(cancel's status code, the status its body showed, the job's final status) for each try; the cancels
    are sent from 0 to 1.2 times a render's time after the submit's answer (the last pass, the final image
    and its files are in that sweep, whatever the machine's speed)."""
    seconds = render_seconds(http)
    out = []
    for k in range(tries):
        job = submit(http, race_scene(k))
        time.sleep((k % 15) / 15 * 1.2 * seconds)
        r = http.delete(f"/api/jobs/{job['id']}")
        assert r.status_code in AGREES, r.text
        shown = r.json()["status"] if r.status_code != 409 else "ended"
        final = wait_finished(http, job["id"], timeout=120)["status"]
        out.append((r.status_code, shown, final))
    return out


def check(outcomes: list[tuple[int, str, str]]) -> None:
    wrong = [(code, final) for code, _, final in outcomes if final not in AGREES[code]]
    assert not wrong, f"the cancel's answer and the job's end disagree: {wrong} (all: {outcomes})"
    assert all(shown == {200: "cancelled", 202: "running", 409: "ended"}[code] for code, shown, _ in outcomes)


def test_cancel_race_embedded_answer_agrees_with_the_end(client):
    outcomes = submit_then_cancel(client)
    check(outcomes)
    assert {code for code, _, _ in outcomes} & {202, 409}, outcomes  # the sweep reached running jobs


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """redis-server, the API with --redis (no workers of its own) and one worker host, on loopback."""
    root = tmp_path_factory.mktemp("cancel-rq")
    with RedisServer(root / "redis.log") as redis_server:
        api = Api(root / "data", redis_server.url).start()
        host = Process(worker_argv(redis_server.url, "host-a", threads=2), root / "host-a.log").start()
        try:
            api.wait_hosts(1)
            yield api
        finally:
            host.stop()
            api.stop()


def test_cancel_race_redis_answer_agrees_with_the_end(cluster):
    outcomes = submit_then_cancel(cluster.client)
    check(outcomes)
    assert {code for code, _, _ in outcomes} & {202, 409}, outcomes
