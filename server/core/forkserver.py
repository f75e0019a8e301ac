"""Imported by the server's forkserver only, first of its preloads (server/core/children.py): it ignores SIGTERM,
as the children it forks do (each ignores it itself too), so that the process group's stop signal leaves it to its
server. Its children inherit this; Ctrl-C (SIGINT) the forkserver ignores by itself."""

from __future__ import annotations

import signal

signal.signal(signal.SIGTERM, signal.SIG_IGN)
