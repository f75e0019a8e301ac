"""python -m tests.support.zygote_probe ARGS: prints what a started process was given (tests/test_support_zygote.py
starts it forked from a zygote and exec'd, and compares)."""

import os
import resource
import sys

print("name", __name__, "file", os.path.basename(sys.argv[0]), "args", sys.argv[1:])
print("env", os.environ.get("TRACER_PROBE"), "cwd", os.getcwd(), "own session", os.getsid(0) == os.getpid())
print("umask", oct(os.umask(0)), "open files", resource.getrlimit(resource.RLIMIT_NOFILE))
print("fds", sorted(int(fd) for fd in os.listdir("/proc/self/fd")), "path0", sys.path[0])  # 3: the listing's own
sys.exit(int(os.environ.get("TRACER_PROBE_EXIT", "0")))
