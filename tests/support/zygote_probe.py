"""python -m tests.support.zygote_probe ARGS: prints what a started process was given (tests/test_support_zygote.py
starts it forked from a zygote and exec'd, and compares). With TRACER_PROBE_FORKSERVER set, it then changes its own
state as a server does before its pools start (a variable, its directory, its open-files limit, a signal), starts
a child from the server's forkserver (server/core/children.py) and prints what the forkserver and the child were
given."""

import os
import resource
import signal
import sys


def _signals(pid: int | str) -> str:
    """The ignored and caught signals of a process, as /proc says them (hex masks)."""
    with open(f"/proc/{pid}/status") as f:
        lines = dict(line.rstrip("\n").split(":\t", 1) for line in f if ":\t" in line)
    return f"ignored {lines['SigIgn']} caught {lines['SigCgt']}"


def _umask() -> str:
    mask = os.umask(0)
    os.umask(mask)
    return oct(mask)


def _stat(pid: int | str) -> list[str]:
    with open(f"/proc/{pid}/stat") as f:
        return f.read().rsplit(")", 1)[1].split()  # state, ppid, pgrp, session, ...


def child(probe: int) -> None:
    """In the forkserver's child: what it and its forkserver were given, relative to the probe."""
    forkserver = os.getppid()
    fs = _stat(forkserver)
    print("forkserver: the probe's child", fs[1] == str(probe), "its group", fs[2] == str(os.getpgid(probe)))
    print("forkserver: its session", fs[3] == str(os.getsid(probe)), _signals(forkserver))
    print("child: its session", os.getsid(0) == os.getsid(probe), _signals("self"))
    print("child: env", os.environ.get("TRACER_PROBE_LATER"), "cuda", repr(os.environ.get("CUDA_VISIBLE_DEVICES")))
    print("child: cwd", os.getcwd(), "umask", _umask(), "open files", resource.getrlimit(resource.RLIMIT_NOFILE))
    print("child: imported", all(m in sys.modules for m in ("numpy", "warp", "tracer.rendering.progressive")))
    with open(f"/proc/{forkserver}/cmdline", "rb") as f:
        print("forkserver: command", f.read().replace(b"\0", b" ").decode().strip()[:120])  # which one: it differs
    print("child: fds", len(os.listdir("/proc/self/fd")), "argv", sys.argv, "main", sys.modules["__main__"].__name__)
    sys.stdout.flush()


def main() -> None:
    print("name", __name__, "file", os.path.basename(sys.argv[0]), "args", sys.argv[1:])
    print("env", os.environ.get("TRACER_PROBE"), "cwd", os.getcwd(), "own session", os.getsid(0) == os.getpid())
    print("umask", _umask(), "open files", resource.getrlimit(resource.RLIMIT_NOFILE))
    print("fds", sorted(int(fd) for fd in os.listdir("/proc/self/fd")), "path0", sys.path[0])  # 3: the listing's
    print("globals", sorted(globals()))  # the module's own names and the interpreter's, nothing else
    sys.stdout.flush()
    if os.environ.get("TRACER_PROBE_FORKSERVER"):
        from server.core.children import context

        os.environ["TRACER_PROBE_LATER"] = "set after the start"
        signal.signal(signal.SIGUSR1, signal.SIG_IGN)  # ignored after the start: so in an exec'd forkserver too
        os.chdir(os.environ["TRACER_PROBE_FORKSERVER"])
        soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft - 1, hard))
        if os.environ.get("TRACER_PROBE_KILL_AHEAD"):  # the forkserver forked ahead killed first: an exec'd one
            for pid in os.listdir("/proc"):
                if pid.isdigit() and _stat(pid)[1] == str(os.getpid()):
                    os.kill(int(pid), signal.SIGKILL)
        proc = context(mesh_reader=False).Process(target=child, args=(os.getpid(),))
        proc.start()
        proc.join(60)
        print("child: exit status", proc.exitcode)
    sys.exit(int(os.environ.get("TRACER_PROBE_EXIT", "0")))


if __name__ == "__main__":
    main()
