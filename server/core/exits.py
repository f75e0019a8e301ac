"""How the service's processes end once everything they did is on disk."""

from __future__ import annotations

import logging
import os
import sys
import time
from typing import NoReturn


def exit_now(status: int = 0) -> NoReturn:
    """End this process at once, its log and output flushed, skipping the interpreter's teardown: freeing
    Warp's, numpy's and pydantic's modules one object at a time took 1-4 s of a stopping server and of each
    of its worker processes on this loaded 2-core machine (issue #25). Only for a process whose state is all
    written: its job given back, its database committed, its children stopped."""
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed or broken pipe: nothing more can be said
            pass
    os._exit(status)


class Stopping:
    """Whether a process has been asked to stop, read by calling it; set by a signal handler. A plain flag, not an
    Event: a handler may set it at any moment, even inside another handler's run, and an Event's lock taken again
    there would hang the process for good (the server's stop, a worker host's and its work horse's)."""

    def __init__(self) -> None:
        self.asked = False

    def set(self) -> None:
        self.asked = True

    def __call__(self) -> bool:
        return self.asked

    def wait(self, seconds: float) -> bool:
        """Sleep `seconds`, or less if asked to stop meanwhile; whether it was."""
        deadline = time.monotonic() + seconds
        while not self.asked and time.monotonic() < deadline:
            time.sleep(min(0.1, max(0.0, deadline - time.monotonic())))
        return self.asked
