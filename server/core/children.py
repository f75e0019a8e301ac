"""How the server's pools start their processes (the render workers, the scene checkers, the grading processes):
from one forkserver per server, which has imported what they all import (numpy, Warp, the tracer, trimesh) once.
A child is a fork of it: it skips those imports (about a second of CPU each) and only loads its kernels (from
Warp's cache, per process). Nothing of the server's own state (threads, locks, open databases) crosses: the
forkserver is a fresh interpreter, never a fork of the server; the children get their plain data as before.

The forkserver ignores SIGTERM (server/core/forkserver.py): a terminal's Ctrl-C or `kill -- -PGID` reaches the
server's whole process group, and a forkserver ended by it would look like the death of every child (their exit
codes come through it). It ends with its server, once every child it forked has ended too: each child holds its
"alive" pipe (to start processes of its own), which it waits to see closed. A child that must end with its server
even in the middle of a task (a scene check, a grading task) therefore watches the server itself, never its parent
(`watch_server`): the two would wait for each other."""

from __future__ import annotations

import multiprocessing as mp
import os
import select
import threading
import time
from multiprocessing.context import ForkServerContext

# what the forkserver imports as it starts, in order (names, not imports: the layers above server/core are the
# children's); a module that cannot be imported there is left out of it (its children import it themselves)
PRELOAD = [
    "server.core.forkserver",  # first: deaf to the group's SIGTERM
    "numpy",
    "warp",
    "trimesh",  # the mesh reader (tracer.assets.import_mesh_reader)
    "tracer.rendering.progressive",  # the render workers' kernels' modules
    "tracer.tools.pixel_samples",  # the checkers'
    "server.queue.embedded.worker",
    "server.checkers.tasks",
]


def context(mesh_reader: bool = True) -> ForkServerContext:
    """The start method of every pool's processes: the forkserver, started by the first child, with PRELOAD
    (without the mesh reader when `mesh_reader` is off: TRACER_PRELOAD_MESH_READER)."""
    ctx = mp.get_context("forkserver")
    assert isinstance(ctx, ForkServerContext)  # for the checker: get_context's type is the base's
    ctx.set_forkserver_preload(PRELOAD if mesh_reader else [m for m in PRELOAD if m != "trimesh"])
    return ctx


SERVER_CHECK = 1.0  # seconds between a child's looks at whether its server is still there, where there is no pidfd


def watch_server(server: int) -> None:
    """In a pool's child: end this process (at once, mid-task or not) when the server `server` has ended, killed
    without a word included (SIGKILL, out of memory). Call it while the server waits for the child's start."""
    threading.Thread(target=_watch, args=(server,), name="server-watch", daemon=True).start()


def _watch(server: int) -> None:
    try:
        fd = os.pidfd_open(server)  # readable once the process has ended
    except ProcessLookupError:
        os._exit(0)
    except OSError:  # no pidfd (a kernel before 5.3): look every SERVER_CHECK seconds
        while _alive(server):
            time.sleep(SERVER_CHECK)
        os._exit(0)
    select.select([fd], [], [])
    os._exit(0)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
