"""The links of `python -m server.lti try --keep` in Chromium, as an admin follows them after the try (server/lti/
trial.py, docs/lti.md "Try it without an LMS"): the pretend LMS's course page launches the tool as the student
through the real OIDC flow in the browser (the tool's login, the LMS's self-posting answer, the launch) onto their
assignment page, and as the instructor onto the course page; the LMS's gradebook shows the grade the try sent. The
try is a process of its own (it starts the tool); its output is read line by line with a deadline, and SIGTERM ends
it (exit 0, the tool it started stopped)."""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from types import SimpleNamespace

from tests.support.page import DESKTOP, Page
from tests.support.scene import ROOT

RUN_SECONDS = 720  # the try until it serves its links, on a loaded 2-core machine (about 90 s quiet)
NAME = "HW 4: glass, mirrors and soft shadows"


def lines_until(proc: subprocess.Popen, marker: str, seconds: float, got: queue.Queue) -> str:
    """The process's output up to the line that starts with `marker` (or its end), read within `seconds`; a
    thread reads every line into `got` (None at the end): the rest is read from there, never from the pipe."""
    threading.Thread(target=lambda: [got.put(x) for x in proc.stdout] + [got.put(None)], daemon=True).start()
    out, until = [], time.monotonic() + seconds
    while time.monotonic() < until:
        try:
            line = got.get(timeout=max(0.1, until - time.monotonic()))
        except queue.Empty:
            break
        if line is None:
            break
        out.append(line)
        if line.startswith(marker):
            return "".join(out)
    raise AssertionError(f"no {marker!r} line within {seconds:.0f} s (exit {proc.poll()}):\n{''.join(out)}")


def test_web_lti_try_s_links_launch_the_tool_through_the_lms_in_a_browser(browser):
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRACER_")}
    proc = subprocess.Popen([sys.executable, "-m", "server.lti", "try", "--keep", "--timeout", "600"], cwd=ROOT,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    try:
        got: queue.Queue = queue.Queue()
        out = lines_until(proc, "Running until Ctrl-C", RUN_SECONDS, got)
        assert "The whole flow works." in out, out
        lms = re.search(r"the pretend LMS's course page .*: (\S+)", out)[1].rstrip("/")
        tool = re.search(r"^The tool: (\S+)", out, re.M)[1]
        p = Page(browser, SimpleNamespace(url=tool), DESKTOP)
        missing: list[str] = []
        try:
            page = p.page
            page.on("response", lambda r: r.status >= 400 and missing.append(f"{r.status} {r.url}"))
            page.goto(lms + "/")
            page.click("text=student")  # the LMS's link: the tool's login, the LMS's answer, the launch
            page.wait_for_url(re.compile(r"/assignments/[0-9a-f]{32}$"))  # the token left the address
            page.wait_for_function("(name) => document.body.innerText.includes(name)", arg=NAME)
            page.goto(lms + "/gradebook")
            book = page.inner_text("body")
            assert "student-1" in book and "/ 13" in book and "1 score(s) received." in book, book
            page.goto(lms + "/start/instructor")
            page.wait_for_url(re.compile(r"/course"))
            page.wait_for_function("(name) => document.body.innerText.includes(name)", arg=NAME)
            p.shot("lti-try-instructor")
        finally:
            p.context.close()
        assert p.unexpected_errors() == [], missing
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=90)
    rest = "".join(iter(lambda: got.get(timeout=30), None))  # what it said after, read by lines_until's thread
    assert proc.returncode == 0, rest
    assert "stopped" in rest
