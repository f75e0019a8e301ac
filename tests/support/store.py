"""A job added to a job store as the service adds one (tests/server/jobs/test_store.py and the store's other tests)."""

from __future__ import annotations

import json

from server.jobs.store import JobStore


def add(store: JobStore, priority: int = 0, max_queued: int = 100) -> str:
    row = store.create(
        json.dumps({"camera": {}}), name=None, width=4, height=4, spp=1, priority=priority, warnings=[],
        max_seconds=60, max_queued=max_queued,
    )  # fmt: skip
    return row["id"]
