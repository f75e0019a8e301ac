"""python -m server [--host H] [--port P] [--data-dir DIR]"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import uvicorn

from server.main import create_app
from server.settings import Settings


def main(argv: list[str] | None = None) -> None:
    s = Settings()
    p = argparse.ArgumentParser(prog="server", description="Serve the ray tracing app and its API.")
    p.add_argument("--host", default=s.host)
    p.add_argument("--port", type=int, default=s.port)
    p.add_argument("--data-dir", default=str(s.data_dir))
    p.add_argument("--workers", type=int, default=1, help="render workers (jobs arrive with the job queue)")
    args = p.parse_args(argv)
    s.host, s.port, s.data_dir = args.host, args.port, Path(args.data_dir)
    s.data_dir.mkdir(parents=True, exist_ok=True)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("server").info("serving on http://%s:%d (data in %s)", s.host, s.port, s.data_dir)
    uvicorn.run(create_app(s), host=s.host, port=s.port, log_level="info")


if __name__ == "__main__":
    main()
