"""The jobs table (SCHEMA) and its rows, typed: `JobRow` (every column but the scene) and `JobRowWithScene`
(the whole row), as the job store (server/jobs/store.py) returns them."""

from __future__ import annotations

import sqlite3
from typing import TypedDict, cast

SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    id TEXT PRIMARY KEY,                    -- secrets.token_urlsafe: unguessable
    status TEXT NOT NULL,                   -- JobStatus
    priority INTEGER NOT NULL DEFAULT 0,    -- higher first
    created_at REAL NOT NULL,               -- Unix time (s)
    started_at REAL,                        -- when a worker took it (latest attempt)
    finished_at REAL,
    name TEXT,                              -- the scene's name
    scene TEXT NOT NULL,                    -- the scene JSON, as submitted
    warnings TEXT NOT NULL DEFAULT '[]',    -- [{path, message}] from validation
    width INTEGER NOT NULL,
    height INTEGER NOT NULL,
    spp INTEGER NOT NULL,
    max_seconds REAL NOT NULL,              -- render time limit of this job
    samples_done INTEGER NOT NULL DEFAULT 0, -- the renderer's progress units (pixel samples; adaptive: pixel passes)
    samples_total INTEGER NOT NULL,
    passes_done INTEGER NOT NULL DEFAULT 0,
    spp_done INTEGER NOT NULL DEFAULT 0,
    rays TEXT NOT NULL DEFAULT '{}',        -- rays by kind, as of the latest pass
    preview INTEGER NOT NULL DEFAULT 0,     -- pass number of the image on disk (0 = none)
    error TEXT,                             -- why it failed or stopped
    errors TEXT NOT NULL DEFAULT '[]',      -- scene errors found by the worker
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    attempts INTEGER NOT NULL DEFAULT 0,    -- times a worker took it
    worker INTEGER,                         -- pid of the embedded worker rendering it
    solve TEXT,                             -- the radiosity solve so far (JSON: fraction, shots, rays, ...)
    host TEXT,                              -- the worker host (name) of the latest try
    device TEXT,                            -- the device the latest try renders on (cpu, cuda:0)
    lost INTEGER NOT NULL DEFAULT 0,        -- tries lost with their worker (a crash, a dead or cut-off host)
    tries TEXT NOT NULL DEFAULT '[]',       -- each try: {attempt, host, device, worker, started_at, ended_at, outcome}
    kind TEXT NOT NULL DEFAULT 'render',    -- JobKind: render, raytree
    lane TEXT NOT NULL DEFAULT 'interactive', -- Lane: interactive first, then batch
    params TEXT NOT NULL DEFAULT '{}',      -- a ray tree's {x, y, sample}
    estimate REAL,                          -- seconds the render was estimated to take on one worker
    snapshot INTEGER NOT NULL DEFAULT 0,    -- the pass of the film saved in the job's snapshot file (0: none)
    owner TEXT,                             -- SHA-256 (hex) of the token that made it; NULL: the instructor's
    result_key TEXT,                        -- a render's pixels' key (server/jobs/results.py); NULL: not answered again
    answered_from TEXT                      -- the done job whose files answered this one at submit (NULL: rendered)
);
"""


class JobRow(TypedDict):
    """A job's row as the store returns it (SCHEMA's columns, JSON ones as their text), its scene left out
    (`peek`, `rows`: the scene may be megabytes): what the job service, the queues and `JobPublic.from_row` read,
    so that the type checker knows its keys. `JobRowWithScene`: the whole row (`get`, `SELECT *`)."""

    id: str
    status: str  # a JobStatus
    priority: int
    created_at: float
    started_at: float | None
    finished_at: float | None
    name: str | None
    warnings: str  # JSON: [{path, message}]
    width: int
    height: int
    spp: int
    max_seconds: float
    samples_done: int
    samples_total: int
    passes_done: int
    spp_done: int
    rays: str  # JSON: {kind: count}
    preview: int
    error: str | None
    errors: str  # JSON: [{path, message}]
    cancel_requested: int
    attempts: int
    worker: int | None
    solve: str | None  # JSON
    host: str | None
    device: str | None
    lost: int
    tries: str  # JSON: [{attempt, host, device, worker, started_at, ended_at, outcome}]
    kind: str  # a JobKind
    lane: str  # a Lane
    params: str  # JSON
    estimate: float | None
    snapshot: int
    owner: str | None
    result_key: str | None
    answered_from: str | None


class JobRowWithScene(JobRow):
    scene: str  # the scene JSON, as submitted


def job_row(row: sqlite3.Row) -> JobRowWithScene:
    """A row of `SELECT *` from the jobs table, typed."""
    return cast(JobRowWithScene, dict(row))


def job_row_sceneless(row: sqlite3.Row) -> JobRow:
    """A row of every column but the scene (`JobStore._sceneless`), typed."""
    return cast(JobRow, dict(row))
