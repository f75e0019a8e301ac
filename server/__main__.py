"""python -m server [--host H] [--port P] [--data-dir DIR] [--workers N] [--redis URL | --redis-url-file PATH]
[--settings FILE] [--check]

and the data directory's upkeep (docs/service.md, "Backups and upgrades"):

    python -m server migrate [--data-dir DIR]            bring its database to this release's schema
    python -m server migrate --dry-run [--data-dir DIR]  what `migrate` would do, and about how long it takes
    python -m server backup DEST [--data-dir DIR]        a consistent copy, a server running or not
    python -m server restore SRC [--data-dir DIR] [--force]   a backup back into an empty data directory
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

import h11
import uvicorn
from pydantic import ValidationError
from uvicorn.protocols.http.h11_impl import H11Protocol

from server.core.backup import backup, restore
from server.core.exits import exit_now
from server.core.files import private_files
from server.core.migrations import migrate, plan
from server.core.settings import explain, load_settings
from server.core.startup import (
    FILES_PER_CONNECTION,
    OWN_FILES,
    StartupError,
    check_data_dir,
    lock_data_dir,
    raise_open_files,
)

GRACEFUL_SECONDS = 5  # a stopping server waits this long at most for its open connections (event streams end at once)
HEADER_BYTES = 16384  # a request's line and headers, at most (h11's own default, said here): 400 past it
log = logging.getLogger("server")
TIMED_OUT = b"HTTP/1.1 408 Request Timeout\r\ncontent-length: 0\r\nconnection: close\r\n\r\n"


UPKEEP = ("migrate", "backup", "restore")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in UPKEEP:
        upkeep(argv)
        return
    p = argparse.ArgumentParser(prog="server", description="Serve the ray tracing app, its API and render workers.")
    p.add_argument("--settings", help="a settings file of TRACER_*=value lines (default: $TRACER_SETTINGS_FILE)")
    p.add_argument("--host", help="address to listen on (default 127.0.0.1, or TRACER_HOST)")
    p.add_argument("--port", type=int, help="TCP port (default 8000, or TRACER_PORT)")
    p.add_argument("--data-dir", help="job database and images (default ./data, or TRACER_DATA_DIR)")
    p.add_argument(
        "--workers", type=int, help="render worker processes (default 1, or TRACER_WORKERS); 0: the API alone"
    )
    p.add_argument(
        "--redis",
        dest="redis_url",
        help="Redis URL: jobs go to worker hosts (python -m server.worker --redis URL) through RQ "
        "(or TRACER_REDIS_URL); without it the workers are processes of this host",
    )
    p.add_argument(
        "--redis-url-file",
        metavar="PATH",
        help="a file whose first line is the Redis URL, password included (or TRACER_REDIS_URL_FILE): unlike "
        "--redis, never shown by ps",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="check the command line, the settings and the data directory, say what would start, and exit (0) "
        "without serving: a unit's ExecStart with --check (deploy/)",
    )
    args = p.parse_args(argv)
    given = {k: v for k, v in vars(args).items() if k not in ("settings", "check") and v is not None}
    try:
        settings = load_settings(args.settings, **given)
    except ValidationError as exc:  # each setting by the name it was given (an option, or its TRACER_ variable)
        p.error(explain(exc, {a.dest: a.option_strings[0] for a in p._actions if a.dest in given}))
    except FileNotFoundError as exc:
        p.error(str(exc))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:  # what is wrong with the data directory, and what to do: one message, no traceback, nothing changed
        check_data_dir(settings.data_dir)
        if args.check:  # no lock (a running server holds it), no migration: nothing changed
            log.info("check: would serve on http://%s:%d (data in %s; %s)", settings.host, settings.port,
                     settings.data_dir, settings.processes_text())  # fmt: skip
            return
        lock = lock_data_dir(settings.data_dir)
        migrate(settings.data_dir)  # here, for a clear message if it cannot (the lifespan finds it done)
    except StartupError as exc:
        log.error("cannot start: %s", exc)
        raise SystemExit(1) from None
    before, after, connections = raise_open_files(settings.max_connections)
    if connections < settings.max_connections:
        want = settings.max_connections * FILES_PER_CONNECTION + OWN_FILES
        log.warning("open files limited to %d (the hard limit): room for %d connections at once, not "
                    "TRACER_MAX_CONNECTIONS=%d (503 past them); raise it to %d (systemd: LimitNOFILE=)", after,
                    connections, settings.max_connections, want)  # fmt: skip
    elif after != before:
        log.info("open files: soft limit raised from %d to %d for TRACER_MAX_CONNECTIONS", before, after)
    log.info(
        "serving on http://%s:%d (data in %s; %s)",
        settings.host,
        settings.port,
        settings.data_dir,
        settings.processes_text(),
    )
    from server.main import create_app  # here: the upkeep commands need none of the app (its imports take seconds)

    app = create_app(settings)
    app.state.data_lock = lock
    config = uvicorn.Config(
        app, host=settings.host, port=settings.port, log_level="info", timeout_graceful_shutdown=GRACEFUL_SECONDS,
        http=deadline_protocol(settings.header_timeout, settings.body_timeout),
        limit_concurrency=connections, h11_max_incomplete_event_size=HEADER_BYTES,
    )  # fmt: skip
    server = StoppingServer(config, app.state.stopping)
    try:
        server.run()
    except KeyboardInterrupt:  # uvicorn raises Ctrl-C's signal again once it has shut down
        pass
    if not server.started:
        raise SystemExit(3)  # uvicorn's own status when the app cannot start (the port taken, ...)
    exit_now()  # stopped: jobs given back, workers and checkers gone, the data directory's lock let go


def upkeep(argv: list[str]) -> None:
    """`migrate`, `backup DEST`, `restore SRC`: one line of JSON on stdout (the report or the manifest's summary);
    a problem is one message on stderr and exit status 1."""
    p = argparse.ArgumentParser(prog=f"server {argv[0]}")
    p.add_argument("--settings", help="a settings file of TRACER_*=value lines (default: $TRACER_SETTINGS_FILE)")
    p.add_argument("--data-dir", help="the data directory (default ./data, or TRACER_DATA_DIR)")
    if argv[0] == "migrate":
        p.add_argument("--dry-run", action="store_true", help="say what it would do and an estimate; change nothing")
    if argv[0] == "backup":
        p.add_argument("dest", type=Path, help="a new (or empty) folder for the backup")
    if argv[0] == "restore":
        p.add_argument("src", type=Path, help="a backup's folder (made by `python -m server backup`)")
        p.add_argument("--force", action="store_true", help="replace what the data directory holds")
    args = p.parse_args(argv[1:])
    given = {"data_dir": args.data_dir} if args.data_dir else {}
    try:
        settings = load_settings(args.settings, **given)
    except (ValidationError, FileNotFoundError) as exc:
        p.error(str(exc))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    private_files()  # a backup, a restore: the server user's alone, as the data directory (0700, 0600)
    data = settings.data_dir
    try:
        if argv[0] == "migrate" and args.dry_run:
            out = plan(data)
            for step in out["steps"]:
                log.info("migrate --dry-run: %s", step)
            log.info("migrate --dry-run: about %.0f s in all; nothing was changed", out["estimate_s"])
        elif argv[0] == "migrate":
            check_data_dir(data)
            lock = lock_data_dir(data)  # not under a running server (an older release may be serving it)
            try:
                r = migrate(data)
            finally:
                lock.close()
            out = {"before": r.before, "after": r.after, "new": r.new, "applied": r.applied,
                   "backup": str(r.backup) if r.backup else None}  # fmt: skip
        elif argv[0] == "backup":
            m = backup(data, args.dest)
            out = {"backup": str(args.dest), "time": m["time"], "schema_version": m["schema_version"],
                   "rows": sum(m["rows"].values()), "files": m["file_count"]}  # fmt: skip
        else:
            m = restore(args.src, data, force=args.force)
            out = {"restored": str(args.src), "data_dir": str(data), "time": m["time"],
                   "schema_version": m["schema_version"], "rows": sum(m["rows"].values()),
                   "files": m["file_count"]}  # fmt: skip
    except StartupError as exc:
        log.error("%s: %s", argv[0], exc)
        raise SystemExit(1) from None
    sys.stdout.write(json.dumps(out) + "\n")


class DeadlineProtocol(H11Protocol):
    """uvicorn's HTTP/1.1 protocol (h11) with deadlines, so that a slow client cannot hold a connection: a
    request's headers must have arrived `header_seconds` after the connection opened or its previous answer
    ended (uvicorn waits for them for ever), and its body may pause at most `body_seconds` between two
    chunks. Past either the connection is closed, with a 408 when nothing was answered on it yet. (The
    whole of a JSON body has its own deadline in the request gate, server/core/errors.py.)"""

    header_seconds = 10.0
    body_seconds = 30.0

    def connection_made(self, transport) -> None:
        super().connection_made(transport)
        self.deadline, self.waiting_for = None, None
        self._arm()

    def data_received(self, data: bytes) -> None:
        if self.waiting_for == "body":
            self._arm(again=True)  # the body moved: its pause starts again
        super().data_received(data)
        self._arm()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._arm()

    def connection_lost(self, exc) -> None:
        self._disarm()
        super().connection_lost(exc)

    def _arm(self, again: bool = False) -> None:
        """The deadline of what the connection waits for now: headers (h11's IDLE: between requests, or
        before the first) or body (SEND_BODY); none while the app works or answers."""
        state = self.conn.their_state
        waiting_for = "headers" if state is h11.IDLE else "body" if state is h11.SEND_BODY else None
        if waiting_for == self.waiting_for and not again:
            return
        self._disarm()
        self.waiting_for = waiting_for
        if waiting_for is not None and not self.transport.is_closing():
            seconds = self.header_seconds if waiting_for == "headers" else self.body_seconds
            self.deadline = self.loop.call_later(seconds, self._expired, waiting_for)

    def _disarm(self) -> None:
        if self.deadline is not None:
            self.deadline.cancel()
            self.deadline = None

    def _expired(self, waiting_for: str) -> None:
        self.deadline = None
        if self.transport.is_closing():
            return
        partial = self.conn.trailing_data[0] if waiting_for == "headers" else self.conn.our_state is h11.SEND_RESPONSE
        if partial:  # a request begun and not answered (a connection that sent nothing is closed without a word)
            self.transport.write(TIMED_OUT)
        log.info("%s: connection closed, the request's %s took too long", self.client, waiting_for)
        if self.cycle is not None and not self.cycle.response_complete:
            self.cycle.disconnected = True
            self.cycle.message_event.set()  # the app's receive() answers http.disconnect
        self.transport.close()


def deadline_protocol(header_seconds: float, body_seconds: float) -> type[DeadlineProtocol]:
    """DeadlineProtocol with these deadlines (uvicorn makes one protocol object per connection from a class)."""
    seconds = {"header_seconds": header_seconds, "body_seconds": body_seconds}
    return type("DeadlineProtocol", (DeadlineProtocol,), seconds)


class StoppingServer(uvicorn.Server):
    """uvicorn's server, telling the app the moment it is asked to stop (SIGTERM, SIGINT: Ctrl-C, a service
    manager, `kill -- -PGID`), before it waits for the open connections and runs the app's shutdown: from
    then on the render workers give their jobs back and none is started again, and event streams end."""

    def __init__(self, config: uvicorn.Config, stopping):
        super().__init__(config)
        self.stopping = stopping

    async def startup(self, sockets=None) -> None:
        await super().startup(sockets=sockets)
        if self.started:  # listening: say so (the render workers start once the kernels are loaded)
            c = self.config
            log.info("answering on http://%s:%d: the page works now; renders start once the render kernels are "
                     "loaded (/api/health says \"starting\" until then)", c.host, c.port)  # fmt: skip

    def handle_exit(self, sig, frame) -> None:
        self.stopping.set()  # a plain flag (server/main.py, Stopping): safe in a signal handler
        super().handle_exit(sig, frame)


if __name__ == "__main__":
    main()
