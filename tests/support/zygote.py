"""The tests' servers and worker hosts, forked from a process that has done their imports once.

`python -m server` spends about 1.5 s of CPU on its imports (FastAPI building its models, pydantic, the routes)
before it serves, and a worker host about 1 s on its own (Warp, the tracer, RQ); the suite starts a hundred
servers and fifty hosts. A zygote per command (`server`, `server.worker`) is a fresh interpreter, started like
them, that imports what the command imports and then only forks: each start is a child that takes the caller's
environment, working directory, umask, open-files limit, session and log, and runs the module as `python -m`
does (runpy's own `_run_module_as_main`). What runs is the command's code from its start; only the imports are
done already, in a process that never did anything else (no thread, no open file, no settings read: the server
reads TRACER_* when it starts, never at import).

A start falls back to a plain `subprocess.Popen` (exec) where a fork could differ from it:
- the caller asks (`fork=False`): a test that reads the process's command line (/proc/PID/cmdline shows the
  zygote's), or one that tests the interpreter's start itself;
- the environment differs from the one the zygote imported in by more than TRACER_* settings (and pytest's
  PYTEST_CURRENT_TEST), or the command
  is not `python -m` one of ZYGOTES in the repository's root;
- TRACER_TEST_ZYGOTE=0 in the tests' environment (every start an exec, as before).

A forked process is not the caller's child: `Forked` is what the tests use of `Popen` (pid, poll, wait,
send_signal, terminate, kill, returncode), its exit status read from the zygote, which reaps a child only when
asked, as Popen does (its pid is never reused while a test may still signal it). A zygote ends when its stdin
closes: at the test process's exit, or when the test process dies.

A forked server's pools start their processes from a multiprocessing forkserver, a fresh interpreter that makes
its imports first (another second of CPU): its zygote has made those too, and the forkserver is a process forked
with the server, ready to become it (`_forkserver_ahead`, below).
"""

from __future__ import annotations

import atexit
import importlib
import json
import os
import resource
import runpy
import subprocess
import sys
import threading
import time
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # the repository's: where the commands run (sys.path[0] is theirs)
ZYGOTES = {
    # the command's module, and what its start imports after its own top-level imports (also imported)
    "server": ("server/__main__.py", ["server.main"]),
    "server.worker": (
        "server/worker.py",
        ["tracer.assets", "tracer.kernels.parallel", "tracer.rendering.progressive"],  # host.main's own imports
    ),
    "tests.support.zygote_probe": ("tests/support/zygote_probe.py", []),  # tests/test_support_zygote.py's
}
# variables besides TRACER_* that may differ from the zygote's: nothing reads them at import (pytest names the
# test running in PYTEST_CURRENT_TEST, so it differs at every start); the child gets the caller's, as exec would
RUNTIME_ONLY = {"PYTEST_CURRENT_TEST"}
# the commands whose children start from a multiprocessing forkserver (server/core/children.py): their zygote has
# made the forkserver's imports too, and each start comes with one ready to become its forkserver (below)
FORKSERVER_USERS = {"server", "tests.support.zygote_probe"}
# what a forkserver started here imports itself: its first module's work is its own process's (SIGTERM ignored,
# CUDA hidden), and the tests' servers preload no mesh reader (tests/support/api.py)
FORKSERVER_OWN = {"server.core.forkserver", "trimesh"}
FORKSERVER_MAIN = "from multiprocessing.forkserver import main; "  # how multiprocessing starts one: -c and this
FORKSERVER_ADDRESS = "tests-zygote-forkserver-"  # and the command's pid: where the one ahead of it listens
POLL_SECONDS = 0.02  # a wait's look at whether the process has ended (Popen.wait sleeps up to 0.05 s between)


# -- the zygote (python -m tests.support.zygote MODULE): stdin the requests, stdout the answers, a JSON line each


def _imports_of(path: str) -> list[str]:
    """The modules a file imports at its top level (`import a.b`, `from a.b import c`: a.b)."""
    import ast

    with open(path) as f:
        tree = ast.parse(f.read())
    names = []
    for node in tree.body:
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module != "__future__":
            names.append(node.module)
    return names


def _readline(buf: bytearray) -> bytes:
    while b"\n" not in buf:
        chunk = os.read(0, 65536)
        if not chunk:
            return b""
        buf += chunk
    line, _, rest = bytes(buf).partition(b"\n")
    buf[:] = rest
    return line


def _answer(obj: dict) -> None:
    os.write(1, (json.dumps(obj) + "\n").encode())


def _serve() -> dict | None:
    """Answer requests until stdin ends (None); in a forked child, the request it is to run."""
    buf, ended = bytearray(), {}
    while line := _readline(buf):
        req = json.loads(line)
        if req["op"] == "poll":
            pid = req["pid"]
            if pid not in ended:
                done, status = os.waitpid(pid, os.WNOHANG)
                if done:
                    ended[pid] = os.waitstatus_to_exitcode(status)  # -N: ended by signal N, as Popen says
            _answer({"returncode": ended.get(pid)})
            continue
        ready_r, ready_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(ready_r)
            try:
                _become(req, ready_w)
            except BaseException as exc:  # noqa: BLE001 (said to the caller, then this child ends)
                os.write(ready_w, f"{type(exc).__name__}: {exc}".encode())
                os._exit(127)
            os.close(ready_w)
            return req
        os.close(ready_w)
        failed = b""
        while chunk := os.read(ready_r, 4096):  # end of file: the child is set up (its session, its log)
            failed += chunk
        os.close(ready_r)
        if failed:
            os.waitpid(pid, 0)
            _answer({"error": failed.decode(errors="replace")})
        else:
            _answer({"pid": pid})
    return None


def _become(req: dict, keep: int) -> None:
    """In the child: the process the caller would have started (Popen's set-up), before the module runs."""
    if req["new_session"]:
        os.setsid()
    log = os.open(req["log"], os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.dup2(log, 1)
    os.dup2(log, 2)
    os.closerange(3, keep)  # Popen's close_fds: nothing of the zygote's open but the "set up" pipe
    os.closerange(keep + 1, 65536)
    os.chdir(req["cwd"])
    os.umask(req["umask"])
    resource.setrlimit(resource.RLIMIT_NOFILE, tuple(req["nofile"]))
    os.environ.clear()
    os.environ.update(req["env"])
    sys.argv = ["-m", *req["args"]]  # as the interpreter leaves it for runpy (which sets argv[0] to the file)


def _zygote(module: str) -> None:
    path, later = ZYGOTES[module]
    for name in _imports_of(path) + later:
        importlib.import_module(name)
    if module in FORKSERVER_USERS:
        _import_forkserver_preload()
    _answer({"ready": os.getpid()})
    req = _serve()
    if req is not None:  # a child: the command, as `python -m MODULE ARGS` runs it
        if module in FORKSERVER_USERS:
            _forkserver_ahead()
        main = sys.modules["__main__"] = types.ModuleType("__main__")  # the command's own namespace, not this one's
        main.__annotations__ = {}  # as the interpreter makes it
        runpy._run_module_as_main(module)  # noqa: SLF001 (what -m calls)


# -- a forkserver without its imports: multiprocessing starts one per server (the first child of a pool starts it),
# a fresh interpreter that imports numpy, Warp and the tracer first (about 1.1 s of CPU; server/core/children.py).
# A forked start comes with a process, forked before the command runs (no thread yet, nothing open), that waits to
# become that forkserver: the command's own multiprocessing asks it instead of exec'ing an interpreter, hands it the
# same descriptors and the command's state at that moment (environment, directory, umask, open-files limit, ignored
# signals), and it runs multiprocessing's own forkserver main(), its preloads already imported but FORKSERVER_OWN.
# It is the command's child, in its session and process group, as the exec'd one would be; unasked, it ends with
# the command.


def _import_forkserver_preload() -> None:
    """In the zygote: what the server's forkserver imports, as it imports it (CUDA hidden from Warp)."""
    from server.core.children import PRELOAD

    before = os.environ.get("CUDA_VISIBLE_DEVICES")
    os.environ["CUDA_VISIBLE_DEVICES"] = ""  # as server.core.forkserver sets it for its process tree
    try:
        for name in PRELOAD:
            if name not in FORKSERVER_OWN:
                importlib.import_module(name)
    finally:
        if before is None:
            del os.environ["CUDA_VISIBLE_DEVICES"]
        else:
            os.environ["CUDA_VISIBLE_DEVICES"] = before


def _forkserver_ahead() -> None:
    """In a forked child, before its command runs: fork the process that becomes its forkserver when asked. It
    listens on a socket of the abstract namespace named by this process's pid; this process keeps nothing open."""
    import multiprocessing.util
    import signal
    import socket

    command = os.getpid()
    address = f"\0{FORKSERVER_ADDRESS}{command}"
    listener = socket.socket(socket.AF_UNIX)
    listener.bind(address)
    listener.listen(1)
    pid = os.fork()
    if pid == 0:
        # the group's Ctrl-C or SIGTERM: no traceback from a waiting helper, which ends with its command anyway
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        _become_forkserver(listener, command)
        sys.exit(0)  # (main never returns: it ends with SystemExit at its clients' end)
    listener.close()
    spawn, lock, asked = multiprocessing.util.spawnv_passfds, threading.Lock(), []

    def spawnv_passfds(path, args, passfds):
        with lock:
            if asked or not args or not str(args[-1]).startswith(FORKSERVER_MAIN):
                return spawn(path, args, passfds)  # another helper (the resource tracker), or a second forkserver
            asked.append(pid)
        called = []  # main(listener_fd, alive_r, preload, **data), as multiprocessing wrote the call
        exec(args[-1][len(FORKSERVER_MAIN) :], {"main": lambda *a, **kw: called.append((a, kw))})  # noqa: S102
        (fd, alive, preload), data = called[0]
        state = {
            "preload": preload, "data": data, "env": dict(os.environ), "cwd": os.getcwd(), "umask": _umask(),
            "nofile": list(resource.getrlimit(resource.RLIMIT_NOFILE)),
            "ignored": _status("SigIgn", 16),  # bit N-1: signal N
        }  # fmt: skip
        try:
            with socket.socket(socket.AF_UNIX) as conn:
                conn.connect(address)
                socket.send_fds(conn, [json.dumps(state).encode()], [fd, alive])
                if conn.recv(16) == b"ok":
                    return pid
        except OSError:
            pass
        return spawn(path, args, passfds)  # the helper is gone (killed): a forkserver exec'd, as without it

    multiprocessing.util.spawnv_passfds = spawnv_passfds


def _signals_as_execd(ignored: int) -> None:
    """The signal dispositions an interpreter exec'd by a process that ignores `ignored` starts with: exec keeps
    what is ignored and sets the rest to the default, and Python ignores SIGPIPE and SIGXFSZ itself and raises
    KeyboardInterrupt on SIGINT where it is not ignored."""
    import signal

    for sig in signal.valid_signals():
        if sig in (signal.SIGKILL, signal.SIGSTOP):
            continue
        if sig in (signal.SIGPIPE, signal.SIGXFSZ) or ignored & (1 << (sig - 1)):
            handler = signal.SIG_IGN
        else:
            handler = signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL
        try:
            signal.signal(sig, handler)
        except (OSError, ValueError):  # one the interpreter may not set (the C library's own)
            pass


def _become_forkserver(listener, command: int) -> None:
    """In the helper: wait for the command's request, then be its forkserver (or end, unasked, with it)."""
    import multiprocessing.forkserver
    import select
    import socket
    import struct

    try:
        gone = os.pidfd_open(command)  # readable once the command has ended
    except OSError:  # no pidfd (a kernel before 5.3): look every second
        gone = None
    while True:
        ready, _, _ = select.select([listener] + ([gone] if gone is not None else []), [], [], None if gone else 1.0)
        if (gone is not None and gone in ready) or os.getppid() != command:
            os._exit(0)  # the command has ended without a forkserver
        if listener not in ready:
            continue
        conn, _ = listener.accept()
        peer = struct.unpack("3i", conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, 12))[0]
        if peer == command:
            break
        conn.close()  # not its command's: another process of the network namespace
    message, fds, _, _ = socket.recv_fds(conn, 1 << 20, 2)
    listener.close()
    if gone is not None:
        os.close(gone)
    state = json.loads(message)
    os.environ.clear()
    os.environ.update(state["env"])
    os.chdir(state["cwd"])
    os.umask(state["umask"])
    resource.setrlimit(resource.RLIMIT_NOFILE, tuple(state["nofile"]))
    sys.argv = ["-c"]  # as `python -c` leaves it
    _signals_as_execd(state["ignored"])  # which main() records for its children
    conn.send(b"ok")
    conn.close()
    multiprocessing.forkserver.main(fds[0], fds[1], state["preload"], **state["data"])


# -- the test process's side -------------------------------------------------------------------------------


class Zygote:
    """One zygote process (for one module), started here; `ask` sends a request and reads its answer."""

    def __init__(self, module: str):
        self.module, self.env = module, dict(os.environ)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.support.zygote", module], cwd=ROOT, env=self.env,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        )  # fmt: skip
        self.lock = threading.Lock()
        ready = self.proc.stdout.readline()
        if not ready:
            raise RuntimeError(f"the zygote of {module} did not start (exit status {self.proc.wait()})")

    def ask(self, req: dict) -> dict:
        with self.lock:
            self.proc.stdin.write((json.dumps(req) + "\n").encode())
            self.proc.stdin.flush()
            line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the zygote of {self.module} has ended (exit status {self.proc.poll()})")
        return json.loads(line)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def close(self) -> None:
        self.proc.stdin.close()  # it ends at the end of its stdin
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)
        self.proc.stdout.close()


class Forked:
    """What the tests use of subprocess.Popen, for a process a zygote forked."""

    def __init__(self, zygote: Zygote, pid: int, args: list[str]):
        self.zygote, self.pid, self.args = zygote, pid, args
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self.zygote.ask({"op": "poll", "pid": self.pid})["returncode"]
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(self.args, timeout)
            time.sleep(POLL_SECONDS)
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:  # not reaped yet: the pid is still this process's
            os.kill(self.pid, sig)

    def terminate(self) -> None:
        self.send_signal(15)

    def kill(self) -> None:
        self.send_signal(9)


_zygotes: dict[str, Zygote] = {}
_zygotes_lock = threading.Lock()


def _zygote_for(module: str) -> Zygote:
    with _zygotes_lock:
        z = _zygotes.get(module)
        if z is None or not z.alive():
            if not _zygotes:
                atexit.register(close_all)
            z = _zygotes[module] = Zygote(module)
        return z


def close_all() -> None:
    """End the zygotes (at this process's exit: registered with atexit at the first one's start)."""
    with _zygotes_lock:
        for z in _zygotes.values():
            z.close()
        _zygotes.clear()


def forkable(argv: list[str], env: dict, cwd) -> str | None:
    """The module of a `python -m MODULE` command a zygote can start as exec would, else None."""
    if len(argv) < 3 or argv[0] != sys.executable or argv[1] != "-m" or argv[2] not in ZYGOTES:
        return None
    if os.path.realpath(cwd) != str(ROOT):
        return None
    base = _zygotes[argv[2]].env if argv[2] in _zygotes else os.environ
    differ = {k for k in set(env) | set(base) if env.get(k) != base.get(k)}
    return argv[2] if all(k.startswith("TRACER_") or k in RUNTIME_ONLY for k in differ) else None


def _status(field: str, base: int) -> int:
    """A number of this process's /proc status (`Umask`: octal, `SigIgn`: hex)."""
    with open("/proc/self/status") as f:
        return int(next(line for line in f if line.startswith(f"{field}:")).split()[1], base)


def _umask() -> int:
    """This process's umask, read without setting it (os.umask would change it for a moment, for every thread)."""
    return _status("Umask", 8)


def start(argv: list[str], *, env: dict, cwd, log, new_session: bool = False, fork: bool = True):
    """`subprocess.Popen(argv, cwd=cwd, env=env, stdout=log, stderr=STDOUT, start_new_session=...)`, forked
    from the command's zygote where it can be (`forkable`); `log` an open file (binary, append) with a name."""
    fork = fork and os.environ.get("TRACER_TEST_ZYGOTE", "1") != "0"
    module = forkable(argv, env, cwd) if fork else None
    if module is None:
        return subprocess.Popen(
            argv, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=new_session
        )
    log.flush()
    umask = _umask()
    req = {
        "op": "start", "args": argv[3:], "env": env, "cwd": str(cwd), "log": log.name, "new_session": new_session,
        "umask": umask, "nofile": list(resource.getrlimit(resource.RLIMIT_NOFILE)),
    }  # fmt: skip
    zygote = _zygote_for(module)
    answer = zygote.ask(req)
    if "error" in answer:
        raise RuntimeError(f"the zygote could not start {' '.join(argv[1:])}: {answer['error']}")
    return Forked(zygote, answer["pid"], argv)


if __name__ == "__main__":
    _zygote(sys.argv[1])
