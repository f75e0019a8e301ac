"""The server's line to one render worker: a socket pair, so no named semaphores to leak.

multiprocessing's Events are named POSIX semaphores that its resource tracker only releases when
the process that made them exits normally; a server stopped by SIGTERM (uvicorn re-raises it after
shutting down) never did, and every stop warned "leaked semaphore objects". A socket pair is two
file descriptors that the kernel closes with the process, whatever ends it.

The protocol, one byte at a time (each write is atomic):
- server -> worker `w`: a job was queued, look at the queue now;
- worker -> server `r`: kernels loaded, ready for jobs;
- the server closing its end (or dying): stop. The worker reads end-of-file, gives its job back
  and exits.
"""

from __future__ import annotations

import os
import select
import threading
from multiprocessing.connection import Connection

WAKE, READY = b"w", b"r"


class ServerEnd:
    """The server's end: wake the worker, hear that it is ready, tell it to stop (close)."""

    def __init__(self, conn: Connection):
        self.conn = conn
        self.fd = conn.fileno()
        os.set_blocking(self.fd, False)  # a wake never blocks the API, even if the worker is busy for long
        self.ready = False
        self._lock = threading.Lock()  # a closed descriptor's number may be reused: never write after close

    def wake(self) -> None:
        with self._lock:
            if self.conn.closed:
                return
            try:
                os.write(self.fd, WAKE)
            except (BlockingIOError, BrokenPipeError, ConnectionResetError):
                pass  # full: wakes are already pending; broken: the worker is gone (the supervisor sees it)

    def is_ready(self) -> bool:
        """True once the worker has said it loaded its kernels."""
        with self._lock:
            if not self.ready and not self.conn.closed:
                try:
                    self.ready = READY in os.read(self.fd, 64)
                except (BlockingIOError, ConnectionResetError):
                    pass
            return self.ready

    def close(self) -> None:
        """Stop: the worker reads end-of-file."""
        with self._lock:
            if not self.conn.closed:
                self.conn.close()


class WorkerEnd:
    """The worker's end: say ready, wait for a wake (or a timeout), and whether to stop."""

    def __init__(self, conn: Connection):
        self.conn = conn
        self.fd = conn.fileno()
        os.set_blocking(self.fd, False)
        self.parent = os.getppid()
        self._stop = False

    def ready(self) -> None:
        try:
            os.write(self.fd, READY)
        except OSError:  # the server is gone: stopping() says so
            self._stop = True

    def wait(self, timeout: float) -> None:
        """Until the server wakes us or asks us to stop, at most `timeout` seconds."""
        if not self._stop:  # poll, not select: the fd may be numbered past select's 1024 (a busy API's fork)
            poller = select.poll()
            poller.register(self.fd, select.POLLIN)
            poller.poll(max(0, int(timeout * 1000)))
        self._drain()

    def stopping(self) -> bool:
        """Asked to stop (the server closed its end), or the server died."""
        if not self._stop:
            self._drain()
        return self._stop or os.getppid() != self.parent

    def _drain(self) -> None:
        """Read the pending wakes; end-of-file means stop."""
        while not self._stop:
            try:
                data = os.read(self.fd, 4096)
            except BlockingIOError:
                return
            except OSError:  # reset: the server is gone
                data = b""
            if not data:
                self._stop = True
