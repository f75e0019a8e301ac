"""python -m server.lti try (server/lti/trial.py, docs/lti.md "Try it without an LMS"), run as an admin runs it: a
process of its own that starts the tool (`python -m server`, one render worker) and plays an LMS on loopback
through registration, an instructor's launch, publishing, deep linking, a student's launch, a graded submission and
the grade received by the LMS; exit 0 and each step's line, the links to open, nothing left behind. Against a
running tool (`--url`, this folder's `tool`: its launches answer the echo page) it names the step that failed and
why, exit 1, and removes the platform it registered. Each run is bounded (a subprocess timeout); the browser's side
of the links is tests/web/test_web_lti_try.py's."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from tests.support.api import INSTRUCTOR
from tests.support.scene import ROOT

STEPS = ["Registration", "An instructor's launch", "The instructor publishes an assignment", "Deep linking",
         "A student's launch", "A submission graded", "The grade at the LMS"]  # fmt: skip
RUN_SECONDS = 720  # the whole try on a loaded 2-core machine: the tool's start and two renders (about 90 s quiet)


def try_command(*args: str, timeout: float = RUN_SECONDS) -> subprocess.CompletedProcess:
    env_drop = ("TRACER_INSTRUCTOR_TOKEN", "TRACER_SETTINGS_FILE", "TRACER_REDIS_URL", "TRACER_DATA_DIR")
    env = {k: v for k, v in os.environ.items() if k not in env_drop}
    return subprocess.run([sys.executable, "-m", "server.lti", "try", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)  # fmt: skip


def test_lti_try_plays_the_whole_flow_against_a_tool_it_starts_and_exits_0():
    done = try_command("--timeout", "600")
    out = done.stdout
    assert done.returncode == 0, out + done.stderr[-3000:]
    for i, step in enumerate(STEPS, 1):
        assert f"{i}. {step} ...\n   ok: " in out, f"step {i} ({step}) not done:\n{out}"
    assert "FAILED" not in out
    assert re.search(r"made course LTI-TRY for the LMS course 'LTI try'", out), out
    assert "the roster read from the LMS (NRPS) lists her, active" in out, out  # a sync then keeps her a student
    assert re.search(r"the LMS received [\d.]+ / 13 for student-1 \(Completed, FullyGraded\)", out), out
    assert "The whole flow works." in out
    for link in ("/start/student", "/start/instructor", "/gradebook", "/assignments/", "/course#token=", "/status"):
        assert link in out, f"no link {link}:\n{out}"
    data = Path(re.search(r"data in (\S+) ", out)[1])
    assert not data.exists() and not data.parent.exists(), "the temporary data directory was left behind"


def test_lti_try_names_the_step_that_failed_and_why(tool):
    """A wrong admin token fails the registration; the right one gets as far as the instructor's launch, where this
    tool (its launch handler the echo page's) shows no picker; the platform it registered is removed again."""
    before = {p["id"] for p in tool.lti.store.platforms()}
    done = try_command("--url", tool.url, "--token", "not-the-admin-token", timeout=120)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "FAILED at step 1. Registration: the tool refused the admin token (401)" in done.stdout, done.stdout

    done = try_command("--url", tool.url, "--token", INSTRUCTOR, timeout=120)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "1. Registration ...\n   ok: " in done.stdout
    assert "FAILED at step 2. An instructor's launch: expected the tool's picker, got: " in done.stdout, done.stdout
    assert "What was done, to look at:" in done.stdout
    assert "/gradebook" in done.stdout
    tool.lti.refresh()
    assert {p["id"] for p in tool.lti.store.platforms()} == before  # its registration removed at the end

    done = try_command("--url", "http://127.0.0.1:9", timeout=60)  # nothing listens there
    assert done.returncode == 1
    assert "FAILED at step 0. The tool: http://127.0.0.1:9 is not answering" in done.stdout
