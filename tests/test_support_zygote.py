"""The zygote the tests' servers and worker hosts are forked from (tests/support/zygote.py): a forked start is the
command's own start (its exit status and words, its session, environment, working directory, umask and
open-files limit, its argv), and what a fork could not give the same way is exec'd."""

from __future__ import annotations

import os
import resource
import subprocess
import sys

from tests.support import zygote
from tests.support.scene import ROOT


def start(tmp_path, argv: list[str], name: str, fork: bool, env: dict | None = None, new_session: bool = False):
    """Start `argv` as the tests' servers are, wait for its end: (the process, its exit status, its log)."""
    with open(tmp_path / name, "ab") as log:
        env = dict(os.environ) if env is None else env
        proc = zygote.start(argv, env=env, cwd=ROOT, log=log, new_session=new_session, fork=fork)
        status = proc.wait(timeout=60)
    return proc, status, (tmp_path / name).read_text()


def test_zygote_a_forked_server_ends_as_an_execd_one_with_the_same_words(tmp_path, monkeypatch):
    monkeypatch.delenv("TRACER_TEST_ZYGOTE", raising=False)  # on, whatever the run says
    argv = [sys.executable, "-m", "server", "--no-such-flag"]  # ends in the server's argument parser
    forked, forked_status, forked_log = start(tmp_path, argv, "forked.log", True)
    execd, execd_status, execd_log = start(tmp_path, argv, "execd.log", False)
    assert isinstance(forked, zygote.Forked)
    assert isinstance(execd, subprocess.Popen)
    assert forked_status == 2
    assert execd_status == 2
    assert forked_log == execd_log
    assert "unrecognized arguments: --no-such-flag" in forked_log
    assert forked.poll() == 2  # asked again: the same answer (the zygote reaped it once)


def test_zygote_a_forked_process_is_given_what_an_execd_one_is(tmp_path, monkeypatch):
    """The probe prints what it was given; forked and exec'd, with a TRACER_ variable the zygote never had, a
    session of its own, another umask, a lower open-files limit and an exit status of 3: the same lines."""
    monkeypatch.delenv("TRACER_TEST_ZYGOTE", raising=False)
    argv = [sys.executable, "-m", "tests.support.zygote_probe", "a", "--b"]
    env = {**os.environ, "TRACER_PROBE": "seen", "TRACER_PROBE_EXIT": "3"}
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    umask = os.umask(0o027)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(soft, 512), hard))
    try:
        forked, forked_status, forked_log = start(tmp_path, argv, "forked.log", True, env, new_session=True)
        execd, execd_status, execd_log = start(tmp_path, argv, "execd.log", False, env, new_session=True)
    finally:
        os.umask(umask)
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    assert isinstance(forked, zygote.Forked)
    assert forked_status == 3
    assert execd_status == 3
    assert forked_log == execd_log
    lines = forked_log.splitlines()
    assert lines[0] == "name __main__ file zygote_probe.py args ['a', '--b']"
    assert lines[1] == f"env seen cwd {ROOT} own session True"
    assert lines[2] == f"umask 0o27 open files ({min(soft, 512)}, {hard})"
    assert lines[3] == f"fds [0, 1, 2, 3] path0 {ROOT}"  # stdin, the log twice, and the listing


def test_zygote_forks_only_what_a_fork_starts_as_exec_would(tmp_path):
    argv = [sys.executable, "-m", "server", "--port", "1"]
    tracer_only = {**os.environ, "TRACER_WORKERS": "3"}
    assert zygote.forkable(argv, tracer_only, ROOT) == "server"
    other = {**os.environ, "PYTHONSTARTUP": "/nowhere"}  # read by the interpreter as it starts: exec'd
    assert zygote.forkable(argv, other, ROOT) is None
    assert zygote.forkable(argv, tracer_only, tmp_path) is None  # elsewhere: sys.path[0] differs
    assert zygote.forkable([sys.executable, "-m", "tracer", "render"], tracer_only, ROOT) is None
    assert zygote.forkable(["python3", "-m", "server"], tracer_only, ROOT) is None
