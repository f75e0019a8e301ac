"""exit_now: a stopped process ends at once, its log flushed, without the interpreter's teardown (the seconds
a stopping server and its workers spent freeing Warp's and numpy's modules, issue #25)."""

from __future__ import annotations

import subprocess
import sys

from tests.support.scene import ROOT

PROGRAM = """
import atexit, logging
atexit.register(print, "teardown ran")
logging.basicConfig(level=logging.INFO)
logging.getLogger("w").info("job given back")
print("buffered", end="")
from server.core.exits import exit_now
exit_now(3)
"""


def test_exits_exit_now_flushes_the_log_and_skips_the_teardown():
    done = subprocess.run([sys.executable, "-c", PROGRAM], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 3, done.stderr
    assert "INFO:w:job given back" in done.stderr  # the log's last line is kept
    assert done.stdout == "buffered"  # output still in Python's buffer is written, and nothing after it
