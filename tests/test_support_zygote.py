"""The zygote the tests' servers and worker hosts are forked from (tests/support/zygote.py): a forked start is the
command's own start (its exit status and words, its session, environment, working directory, umask and
open-files limit, its argv), and what a fork could not give the same way is exec'd."""

from __future__ import annotations

import os
import resource
import signal
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
    assert "ZYGOTES" not in lines[4]  # its own module's names, not the zygote's


def test_zygote_forks_only_what_a_fork_starts_as_exec_would(tmp_path):
    argv = [sys.executable, "-m", "server", "--port", "1"]
    tracer_only = {**os.environ, "TRACER_WORKERS": "3"}
    assert zygote.forkable(argv, tracer_only, ROOT) == "server"
    other = {**os.environ, "PYTHONSTARTUP": "/nowhere"}  # read by the interpreter as it starts: exec'd
    assert zygote.forkable(argv, other, ROOT) is None
    assert zygote.forkable(argv, tracer_only, tmp_path) is None  # elsewhere: sys.path[0] differs
    assert zygote.forkable([sys.executable, "-m", "tracer", "render"], tracer_only, ROOT) is None
    assert zygote.forkable(["python3", "-m", "server"], tracer_only, ROOT) is None


def test_zygote_a_forked_server_s_forkserver_and_its_child_are_given_what_an_execd_one_s_are(tmp_path, monkeypatch):
    """The probe, in a session of its own, changes a variable, its directory and its open-files limit after its
    start (as a server does before its pools start) and ignores SIGUSR1, then starts a child from the server's
    forkserver: forked from the zygote (its forkserver the process forked ahead, its imports made) and exec'd (a
    fresh forkserver), the forkserver is the probe's child in its group and session, deaf to SIGTERM and SIGINT,
    and the child is given the same (the same lines; the signals as the environment has them: CI's background run
    ignores SIGINT from its start)."""
    monkeypatch.delenv("TRACER_TEST_ZYGOTE", raising=False)
    argv = [sys.executable, "-m", "tests.support.zygote_probe"]
    env = {**os.environ, "TRACER_PROBE_FORKSERVER": str(tmp_path)}
    forked, forked_status, forked_log = start(tmp_path, argv, "forked.log", True, env, new_session=True)
    execd, execd_status, execd_log = start(tmp_path, argv, "execd.log", False, env, new_session=True)
    assert isinstance(forked, zygote.Forked)
    assert forked_status == 0, forked_log
    assert execd_status == 0, execd_log
    lines, execd_lines = forked_log.splitlines(), execd_log.splitlines()
    commands = [line for line in lines if line.startswith("forkserver: command")]
    assert commands[0].endswith("-m tests.support.zygote tests.support.zygote_probe"), commands  # the one ahead
    assert "from multiprocessing.forkserver import main" in execd_log, execd_log  # a fresh interpreter
    assert [line for line in lines if line not in commands] == [
        line for line in execd_lines if not line.startswith("forkserver: command")
    ]
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    assert lines[5] == "forkserver: the probe's child True its group True", forked_log
    assert lines[6].startswith("forkserver: its session True ignored "), forked_log
    ignored = int(lines[6].split()[5], 16)
    assert ignored & (1 << (signal.SIGTERM - 1)), lines[6]  # server/core/forkserver.py
    assert ignored & (1 << (signal.SIGINT - 1)), lines[6]  # multiprocessing's forkserver main()
    assert ignored & (1 << (signal.SIGUSR1 - 1)), lines[6]  # as the probe had it when it started the forkserver
    assert lines[7].startswith("child: its session True"), forked_log
    assert lines[8] == "child: env set after the start cuda ''", forked_log
    umask = os.umask(0)
    os.umask(umask)
    assert lines[9] == f"child: cwd {tmp_path} umask {oct(umask)} open files ({soft - 1}, {hard})"
    assert lines[10] == "child: imported True", forked_log
    assert lines[-1] == "child: exit status 0", forked_log


def test_zygote_a_forked_server_whose_forkserver_ahead_was_killed_execs_one(tmp_path, monkeypatch):
    """The process forked ahead to become the forkserver killed before it is asked: the pool's start execs a
    forkserver, as without the zygote, and the child starts from it."""
    monkeypatch.delenv("TRACER_TEST_ZYGOTE", raising=False)
    argv = [sys.executable, "-m", "tests.support.zygote_probe"]
    env = {**os.environ, "TRACER_PROBE_FORKSERVER": str(tmp_path), "TRACER_PROBE_KILL_AHEAD": "1"}
    forked, status, log = start(tmp_path, argv, "forked.log", True, env, new_session=True)
    assert isinstance(forked, zygote.Forked)
    assert status == 0, log
    assert "forkserver: command " in log, log
    assert "from multiprocessing.forkserver import main" in log, log  # exec'd
    assert "child: imported True" in log, log
    assert log.splitlines()[-1] == "child: exit status 0", log
