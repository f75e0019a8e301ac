"""python -m server.worker --redis URL [--device cpu|cuda:0] [--threads N] [--queues ...]: a worker host of
the Redis backend (server/queue/redis/host.py). The embedded backend's workers are processes the API starts
itself (server/queue/embedded/)."""

from __future__ import annotations

import sys

from server.queue.redis.host import main

if __name__ == "__main__":
    sys.exit(main())
