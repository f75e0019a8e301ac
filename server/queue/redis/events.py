"""What the API and the worker hosts of the Redis backend say to each other through Redis.

Work goes out as RQ jobs (one per try: RQ job id `<job id>-try<n>`, in the queue of the job's lane:
`interactive` or `batch`). Everything
comes back as events on one Redis stream, read by the API in a consumer group (so an API that was
down finds what it missed):

    started   a worker host took the try            {host, device, worker}
    progress  the try's progress fields              {fields, files}
    finish    the try ended the job                  {status, fields, files}
    giveback  back to the queue: the host is stopping, or a batch render gives way to interactive
              work                                   {outcome, fields, files}

Each event names its job and try; the API applies it only while the job is still on that try
(server/jobs/store.py fences by `Attempt`), so a lost worker that comes back late never writes into the
job's next try. Files (images, AOVs, a radiosity solution) travel as Redis keys with an expiry,
named in the event that follows them (`files`: {JobFile value: key}); the API copies each into the
job's folder and deletes the key.

Besides, plain keys: the try a job is on (`try:<id>`, which a worker compares with its own to know
it lost the job), a cancel flag (`cancel:<id>`), a host's request that its try give the job back
(`giveback:<id>-try<n>`), each host's description (`host:<worker name>`, refreshed with its
heartbeat), the API's settings for the hosts (`config`), an epoch that tells the API whether
Redis lost its data (`epoch`), and the mark of the one API that uses the database (`api`).
"""

from __future__ import annotations

import json
from enum import StrEnum

from server.jobs.lifecycle import LANES

PREFIX = "tracer:"
STREAM = PREFIX + "events"  # the events of every try, in order
GROUP = "api"  # the API's consumer group on the stream
EPOCH = PREFIX + "epoch"  # set by the API; gone after Redis lost its data
CONFIG = PREFIX + "config"  # hash: lost_after (seconds), for the worker hosts' heartbeats
API = PREFIX + "api"  # held by the one API that uses this Redis database (refreshed; expires if it dies)
API_TTL = 10  # seconds
QUEUES = tuple(str(lane) for lane in LANES)  # the RQ queues, one per lane, in the order hosts take them
STREAM_MAXLEN = 100_000  # events kept (approximately); the API acknowledges as it applies them
BLOB_TTL = 24 * 3600  # seconds a file sent by a worker host waits for the API
FLAG_TTL = 7 * 24 * 3600  # seconds the try, cancel and give-back keys live


class EventKind(StrEnum):
    """The kinds of event on the stream (the table above)."""

    started = "started"
    progress = "progress"
    finish = "finish"
    giveback = "giveback"


def rq_job_id(job_id: str, attempt: int) -> str:
    """The RQ job of a try: `<job id>-try<n>` (RQ allows letters, digits, - and _ only)."""
    return f"{job_id}-try{attempt}"


def parse_rq_job_id(rq_id: str) -> tuple[str, int] | None:
    """`<job id>-try<n>` -> (job id, n); None for an id that is not one of ours (the last `-try` is
    ours: a job id may hold the letters too)."""
    job_id, _, attempt = rq_id.rpartition("-try")
    return (job_id, int(attempt)) if job_id and attempt.isdigit() else None


def try_key(job_id: str) -> str:
    return f"{PREFIX}try:{job_id}"


def cancel_key(job_id: str) -> str:
    return f"{PREFIX}cancel:{job_id}"


def giveback_key(job_id: str, attempt: int) -> str:
    return f"{PREFIX}giveback:{rq_job_id(job_id, attempt)}"


def host_key(worker_name: str) -> str:
    return f"{PREFIX}host:{worker_name}"


def snapshot_key(job_id: str, attempt: int) -> str:
    """The film a try continues from (an earlier try's snapshot), put there by the API for it."""
    return f"{PREFIX}snapshot:{rq_job_id(job_id, attempt)}"


def blob_key(job_id: str, attempt: int, serial: int) -> str:
    return f"{PREFIX}blob:{rq_job_id(job_id, attempt)}:{serial}"


def text(x: bytes | str) -> str:
    """A Redis reply as text (this service's connections answer bytes: decode_responses is off)."""
    return x.decode() if isinstance(x, bytes) else x


def encode(kind: EventKind, job_id: str, attempt: int, **data) -> dict[str, str]:
    """A stream entry: its kind, job, try and data (JSON)."""
    return {"kind": kind.value, "job": job_id, "attempt": str(attempt), "data": json.dumps(data, separators=(",", ":"))}


def decode(fields: dict) -> tuple[str, str, int, dict]:
    """A stream entry (bytes or str fields) -> (kind, job id, try, data); the kind as sent (an EventKind's value,
    or a kind this API does not know, which it leaves alone)."""
    get = {text(k): text(v) for k, v in fields.items()}
    return get["kind"], get["job"], int(get["attempt"]), json.loads(get.get("data") or "{}")
