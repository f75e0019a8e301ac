"""The multi-host harness (tests/hosts.py): namespaces that reach each other and nothing else, a cable
that can be pulled and put back, a host whose every process dies, and nothing left behind."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from tests.support.hosts import Cluster


def _get(c: Cluster, ns: str, url: str, seconds: int = 3) -> subprocess.CompletedProcess:
    argv = ["curl", "-sS", "-m", str(seconds), "-o", "/dev/null", "-w", "%{http_code}", url]
    return c.run(ns, argv, timeout=seconds + 5)


def test_hosts_reach_the_broker_cut_restore_kill_and_clean_up():
    with Cluster(workers=2) as c:
        assert set(Cluster.list()) >= {c.broker, *c.workers}
        # nothing of the cluster's subnet exists in the root namespace (so there nothing routes to it)
        root = subprocess.run(["ip", "-o", "addr"], capture_output=True, text=True, check=True).stdout
        assert c.prefix not in root
        c.popen(c.broker, [sys.executable, "-m", "http.server", "8080", "--bind", c.broker_ip])
        url = f"http://{c.broker_ip}:8080/"
        deadline = time.monotonic() + 20
        while _get(c, c.workers[0], url).stdout != "200":
            assert time.monotonic() < deadline, "the broker's server never answered"
            time.sleep(0.1)
        assert _get(c, c.workers[1], url).stdout == "200"
        # a pulled cable: the host's requests time out (its packets vanish), the other host is unaffected
        c.cut(c.workers[0])
        cut = _get(c, c.workers[0], url, seconds=1)
        assert cut.returncode == 28, cut.stderr  # curl: operation timed out
        assert _get(c, c.workers[1], url).stdout == "200"
        c.restore(c.workers[0])
        assert _get(c, c.workers[0], url).stdout == "200"
        # a host dies: every process in it, one in a session of its own too (as RQ's job processes are)
        c.popen(c.workers[1], ["sh", "-c", "setsid sleep 300 & sleep 300"])
        deadline = time.monotonic() + 10
        while len(c.pids(c.workers[1])) < 3:
            assert time.monotonic() < deadline, "the host's processes did not start"
            time.sleep(0.05)
        killed = c.kill_host(c.workers[1])
        assert len(killed) >= 3 and c.pids(c.workers[1]) == []
    assert not {c.broker, *c.workers} & set(Cluster.list())


def test_hosts_are_removed_when_a_test_fails_inside():
    with pytest.raises(RuntimeError, match="inside"), Cluster(workers=1, tag="rtfail") as c:
        c.popen(c.workers[0], ["sleep", "300"])
        raise RuntimeError("a failure inside the test")
    assert not {"rtfailb", "rtfailw1"} & set(Cluster.list())
