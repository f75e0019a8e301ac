"""python -m server [--host H] [--port P] [--data-dir DIR] [--workers N] [--redis URL] [--settings FILE]"""

from __future__ import annotations

import argparse
import logging

import uvicorn

from server.core.settings import load_settings
from server.core.startup import StartupError, check_data_dir
from server.main import create_app, lock_data_dir

GRACEFUL_SECONDS = 5  # a stopping server waits this long at most for its open connections (event streams end at once)


def main(argv: list[str] | None = None) -> None:
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
    args = p.parse_args(argv)
    given = {k: v for k, v in vars(args).items() if k != "settings" and v is not None}
    try:
        settings = load_settings(args.settings, **given)
    except (FileNotFoundError, ValueError) as exc:  # pydantic's ValidationError is a ValueError
        p.error(str(exc))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    log = logging.getLogger("server")
    try:  # what is wrong with the data directory, and what to do: one message, no traceback, nothing changed
        check_data_dir(settings.data_dir)
        lock = lock_data_dir(settings.data_dir)
    except StartupError as exc:
        log.error("cannot start: %s", exc)
        raise SystemExit(1) from None
    queue = f"Redis at {settings.redis_url}" if settings.redis_url else "embedded"
    log.info(
        "serving on http://%s:%d (data in %s, %d worker(s), queue: %s)",
        settings.host,
        settings.port,
        settings.data_dir,
        settings.workers,
        queue,
    )
    app = create_app(settings)
    app.state.data_lock = lock
    config = uvicorn.Config(
        app, host=settings.host, port=settings.port, log_level="info", timeout_graceful_shutdown=GRACEFUL_SECONDS
    )
    server = StoppingServer(config, app.state.stopping)
    try:
        server.run()
    except KeyboardInterrupt:  # uvicorn raises Ctrl-C's signal again once it has shut down
        pass
    if not server.started:
        raise SystemExit(3)  # uvicorn's own status when the app cannot start (the port taken, ...)


class StoppingServer(uvicorn.Server):
    """uvicorn's server, telling the app the moment it is asked to stop (SIGTERM, SIGINT: Ctrl-C, a service
    manager, `kill -- -PGID`), before it waits for the open connections and runs the app's shutdown: from
    then on the render workers give their jobs back and none is started again, and event streams end."""

    def __init__(self, config: uvicorn.Config, stopping):
        super().__init__(config)
        self.stopping = stopping

    def handle_exit(self, sig, frame) -> None:
        self.stopping.set()  # a plain flag (server/main.py, Stopping): safe in a signal handler
        super().handle_exit(sig, frame)


if __name__ == "__main__":
    main()
