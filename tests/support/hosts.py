"""Several hosts on one machine, for the tests of what crosses a network: Linux network namespaces.

A `Cluster` makes a broker namespace (for Redis and the API) and N worker namespaces. Each worker
joins the broker over a veth pair whose broker end is enslaved to a bridge inside the broker
namespace, so the hosts share one private subnet and nothing of it exists in the root namespace:

    broker  (bridge br0, 10.S.0.1/24)  --veth--  w1 (eth0, 10.S.0.11/24)
                                        --veth--  w2 (eth0, 10.S.0.12/24)

Safety rules (the machine's own network is never touched):
- every client (curl, Python, redis-cli) runs *inside* a namespace (`Cluster.run`, `Cluster.popen`);
  the test process never sends a packet to a namespace's address: from the root namespace there is
  no route, and the packet would leave the machine;
- loops are bounded in count and time (`wait_for`);
- `close()` kills every process in the namespaces (`ip netns pids`) and deletes them, also when a
  test fails (use the cluster as a context manager or a fixture with a finaliser).

Needs root (CI runs as root) and iproute2's `ip`.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

IP = "/usr/sbin/ip" if Path("/usr/sbin/ip").exists() else "ip"


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run([IP, *args], capture_output=True, text=True, check=check, timeout=20)


class Cluster:
    """A broker namespace and `workers` worker namespaces on one bridge; see the module's doc."""

    def __init__(self, workers: int = 2, tag: str | None = None):
        self.tag = tag or f"rt{os.getpid() % 100000}"
        subnet = 16 + os.getpid() % 200  # 10.S.0.0/24: private to these namespaces
        self.prefix = f"10.{subnet}.0"
        self.broker = f"{self.tag}b"
        self.workers = [f"{self.tag}w{k + 1}" for k in range(workers)]
        self.broker_ip = f"{self.prefix}.1"
        self.ips = {name: f"{self.prefix}.{11 + k}" for k, name in enumerate(self.workers)}
        self.ips[self.broker] = self.broker_ip
        self.procs: list[subprocess.Popen] = []
        self.made: list[str] = []

    # -- life ---------------------------------------------------------------------------------

    def __enter__(self) -> Cluster:
        try:
            self.create()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def create(self) -> None:
        if os.geteuid() != 0:
            raise RuntimeError("network namespaces need root (CI runs as root)")
        self.close()  # leftovers of a crashed run with the same names
        for ns in [self.broker, *self.workers]:
            _ip("netns", "add", ns)
            self.made.append(ns)
            self.sh(ns, "ip link set lo up")
        self.sh(self.broker, "ip link add br0 type bridge && ip link set br0 up")
        self.sh(self.broker, f"ip addr add {self.broker_ip}/24 dev br0")
        for k, ns in enumerate(self.workers):
            host_end, peer = f"{self.tag}h{k}", f"{self.tag}p{k}"
            # made in the broker namespace, so neither end ever exists in the root namespace
            self.sh(self.broker, f"ip link add {host_end} type veth peer name {peer}")
            self.sh(self.broker, f"ip link set {peer} netns {ns}")
            self.sh(self.broker, f"ip link set {host_end} master br0 && ip link set {host_end} up")
            self.sh(
                ns, f"ip link set {peer} name eth0 && ip addr add {self.ips[ns]}/24 dev eth0 && ip link set eth0 up"
            )

    def close(self) -> None:
        """Kill every process in the namespaces, then delete them (safe to call twice)."""
        names = [self.broker, *self.workers]
        for ns in names:
            self.kill_host(ns)
        for p in self.procs:
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass
            for stream in (p.stdout, p.stderr):
                if stream is not None:
                    stream.close()
        self.procs.clear()
        existing = set(self.list())
        for ns in names:
            if ns in existing:
                _ip("netns", "del", ns, check=False)
        self.made.clear()

    @staticmethod
    def list() -> list[str]:
        out = _ip("netns", "list", check=False).stdout
        return [line.split()[0] for line in out.splitlines() if line.strip()]

    # -- running things inside ----------------------------------------------------------------

    def sh(self, ns: str, command: str, timeout: float = 20) -> str:
        """Run a shell command inside namespace `ns`; its stdout (raises with stderr on failure)."""
        r = subprocess.run(
            [IP, "netns", "exec", ns, "sh", "-c", command], capture_output=True, text=True, timeout=timeout
        )
        if r.returncode != 0:
            raise RuntimeError(f"[{ns}] {command}: exit {r.returncode}: {r.stderr.strip()}")
        return r.stdout

    def run(self, ns: str, argv: list[str], timeout: float = 30, **kw) -> subprocess.CompletedProcess:
        """Run a program inside `ns` and wait for it."""
        return subprocess.run([IP, "netns", "exec", ns, *argv], capture_output=True, text=True, timeout=timeout, **kw)

    def popen(
        self, ns: str, argv: list[str], log: Path | None = None, env: dict | None = None, **kw
    ) -> subprocess.Popen:
        """Start a program inside `ns` (it keeps running; `close()` kills it). `ip netns exec` execs the
        program, so the Popen's pid is the program's."""
        out = open(log, "ab") if log else subprocess.DEVNULL  # noqa: SIM115 (closed with the process)
        p = subprocess.Popen(
            [IP, "netns", "exec", ns, *argv],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
            **kw,
        )
        if log:
            p.stdout = out  # closed in close()
        self.procs.append(p)
        return p

    def pids(self, ns: str) -> list[int]:
        """Every process that lives in namespace `ns` (whatever its process group or session)."""
        out = _ip("netns", "pids", ns, check=False).stdout
        return [int(x) for x in out.split()]

    def kill_host(self, ns: str) -> list[int]:
        """A host dies: SIGKILL every process in its namespace, its job processes in their own
        sessions included. Returns the pids killed."""
        killed = []
        for _ in range(20):  # processes may fork while we kill: a few rounds, bounded
            pids = self.pids(ns) if ns in self.list() else []
            if not pids:
                break
            for pid in pids:
                try:
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                except ProcessLookupError:
                    pass
            time.sleep(0.05)
        return killed

    def _host_end(self, ns: str) -> str:
        return f"{self.tag}h{self.workers.index(ns)}"

    def cut(self, ns: str) -> None:
        """Pull a worker host's cable: its link's broker end goes down, so its packets vanish (its own
        interface only loses its carrier) and its processes live on, unreachable."""
        self.sh(self.broker, f"ip link set {self._host_end(ns)} down")

    def restore(self, ns: str) -> None:
        self.sh(self.broker, f"ip link set {self._host_end(ns)} up")

    def http(
        self, ns: str, method: str, url: str, body: dict | None = None, timeout: float = 30, headers: dict | None = None
    ) -> tuple[int, dict]:
        """An HTTP request made from inside `ns` (curl): (status, JSON body or {"text": ...})."""
        argv = ["curl", "-sS", "-m", str(int(timeout)), "-X", method, "-o", "-", "-w", "\n%{http_code}"]
        for name, value in (headers or {}).items():
            argv += ["-H", f"{name}: {value}"]
        if body is not None:
            argv += ["-H", "content-type: application/json", "--data-binary", json.dumps(body)]
        r = self.run(ns, [*argv, url], timeout=timeout + 5)
        if r.returncode != 0:
            raise RuntimeError(f"[{ns}] curl {method} {url}: {r.stderr.strip()}")
        text, _, code = r.stdout.rpartition("\n")
        try:
            data = json.loads(text) if text else {}
        except json.JSONDecodeError:
            data = {"text": text}
        return int(code), data

    def fetch(self, ns: str, url: str, path: Path, timeout: float = 30, headers: dict | None = None) -> int:
        """Download a URL from inside `ns` into a file; the HTTP status."""
        argv = ["curl", "-sS", "-m", str(int(timeout)), "-o", str(path), "-w", "%{http_code}"]
        for name, value in (headers or {}).items():
            argv += ["-H", f"{name}: {value}"]
        r = self.run(ns, [*argv, url], timeout=timeout + 5)
        if r.returncode != 0:
            raise RuntimeError(f"[{ns}] curl {url}: {r.stderr.strip()}")
        return int(r.stdout)
