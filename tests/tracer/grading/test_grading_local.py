"""The grading CLI's renderer (tracer/grading/local.py): renders in worker processes of its own, the same
images as in process, a render stuck past its limit killed, a crashed worker replaced. The CLI through it:
test_grading.py (test_cli_grades_a_class_through_the_job_queue)."""

from __future__ import annotations

import json
import os
import signal
import threading
import time

import numpy as np
import pytest

from tests.support.scene import scene_dict, small
from tracer.grading import InlineRenderer, RenderJob
from tracer.grading.local import LocalRenderer


def job(name: str, scene: dict, seconds: float = 60.0, priority: int = 0) -> RenderJob:
    return RenderJob(name=name, scene=json.loads(json.dumps(scene)), max_seconds=seconds, priority=priority)


def long_pass() -> dict:
    """One pass of several seconds on one thread: 2048 x 2048 path-traced pixels at 1 sample."""
    return small(scene_dict("cornell_path"), 2048, 2048, sampler={"type": "jittered", "spp": 4})


def test_grading_local_same_images_as_in_process_and_a_stuck_render_killed(tmp_path):
    quick = [
        job("whitted", small(scene_dict("whitted"), 24, 16, sampler={"type": "jittered", "spp": 4})),
        job("path", small(scene_dict("cornell_path"), 16, 16, sampler={"type": "jittered", "spp": 4}), priority=5),
    ]
    stuck = job("stuck", long_pass(), seconds=0.2)
    seen = []
    log = tmp_path / "workers.log"
    with LocalRenderer(
        workers=2, threads=1, log_path=log, on_progress=lambda d, t: seen.append((d, t)), grace=0.3
    ) as r:
        got = r([*quick, stuck])
        again = r(quick[:1])  # the killed worker was replaced
    inline = InlineRenderer(threads=1)(quick)
    for g, i in zip([*got[:2], *again], [*inline, inline[0]], strict=True):
        assert g.error is None
        assert g.spp == i.spp == 4
        assert np.array_equal(g.image, i.image) and np.array_equal(g.variance, i.variance)
    assert got[2].image is None
    assert got[2].error == (
        "stopped: over the time limit of 0.2 s per render (set by the assignment's limits.max_seconds); "
        "its worker was killed"
    )
    assert seen[0] == (0, 3)
    assert seen[3] == (3, 3)
    assert seen[-1] == (1, 1)
    text = log.read_text()
    assert "render worker" in text
    assert "job whitted: done, 4 spp" in text


def test_grading_local_a_crashed_worker_fails_its_job_alone(tmp_path):
    with LocalRenderer(workers=1, threads=1, log_path=tmp_path / "workers.log") as r:

        def kill_when_busy() -> None:
            while r.pool[0].job is None:
                time.sleep(0.05)
            time.sleep(0.3)
            os.kill(r.pool[0].process.pid, signal.SIGKILL)

        threading.Thread(target=kill_when_busy, daemon=True).start()
        crashed, after = r([job("doomed", long_pass()), job("next", small(scene_dict("whitted"), 8, 8))])
    assert crashed.error == "the render process killed by signal SIGKILL"
    assert after.error is None
    assert after.image.shape == (8, 8, 3)


def test_grading_local_renders_only_inside_its_with_block():
    with pytest.raises(RuntimeError, match="inside its `with` block"):
        LocalRenderer()([job("x", scene_dict("whitted"))])
