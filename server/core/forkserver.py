"""Imported by the server's forkserver only, first of its preloads (server/core/children.py): it ignores SIGTERM,
as the children it forks do (each ignores it itself too), so that the process group's stop signal leaves it to its
server. Its children inherit this; Ctrl-C (SIGINT) the forkserver ignores by itself. It also hides CUDA from
Warp in its process tree (below)."""

from __future__ import annotations

import os
import signal

signal.signal(signal.SIGTERM, signal.SIG_IGN)
# Its children render and check on the CPU only (the embedded backend; a CUDA worker host never forks): CUDA
# initialised here would not survive their fork, so Warp, imported next, sees no CUDA device in this process tree.
os.environ["CUDA_VISIBLE_DEVICES"] = ""
