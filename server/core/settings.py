"""Settings in one place: command line, then environment (TRACER_*), then a settings file, then defaults.

Every field below can be set as an environment variable named TRACER_ + the field name in capitals
(`TRACER_MAX_SPP=1024`), or in a settings file of such lines (`--settings FILE`, or the file named
by TRACER_SETTINGS_FILE). docs/service.md lists them.
"""

from __future__ import annotations

import ipaddress
import os
import re
from pathlib import Path
from typing import Annotated, Any

from pydantic import (
    BeforeValidator,
    ByteSize,
    Field,
    SecretStr,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)
from pydantic_settings import BaseSettings, SettingsConfigDict

from server.core.credentials import MIN_TOKEN_LENGTH, STRONG_TOKEN, loopback_address, masked, redis_url_from, weak_token
from tracer.limits import LIMITS, Limits
from tracer.limits import NAMES as LIMIT_NAMES

UNITS = {"s": 1, "m": 60, "h": 3600, "d": 86400}
# bytes: a request body this large is a large one: its JSON depth is found in a thread, off the event loop, it holds
# a share of TRACER_BODY_BUDGET_BYTES (server/api/gate.py), and its scene waits in the checkers' second line
THREAD_FROM = 65536


def _seconds(v):
    """A duration: a number of seconds, or text such as 90, 90s, 30m, 12h, 7d."""
    if isinstance(v, str):
        m = re.fullmatch(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([smhd]?)\s*", v.lower())
        if m is None:
            raise ValueError(f"expected seconds or a duration such as 90s, 30m, 12h, 7d; got {v!r}")
        return float(m[1]) * UNITS[m[2] or "s"]
    return v


Duration = Annotated[float, BeforeValidator(_seconds)]


# The scene limits, one setting per row of the table in tracer/limits.py (TRACER_MAX_WIDTH, ...), each
# answered with a 422 at the offending field's JSON path: the library's defaults are the service's.
_LIMIT_FIELDS: dict[str, Any] = {
    limit.name: (int, Field(limit.default, ge=1, le=limit.most, description=limit.description)) for limit in LIMITS
}
SceneLimits = create_model("SceneLimits", __base__=BaseSettings, **_LIMIT_FIELDS)


class Settings(SceneLimits):
    model_config = SettingsConfigDict(env_prefix="TRACER_", extra="ignore", validate_assignment=True)

    # Where and how the service runs.
    host: str = Field("127.0.0.1", description="address to listen on")
    port: int = Field(8000, ge=0, le=65535, description="TCP port")
    data_dir: Path = Field(Path("data"), description="job database (jobs.sqlite3) and images (jobs/<id>/)")
    workers: int = Field(
        1,
        ge=0,
        le=64,
        description="render worker processes on this host (with Redis: local worker hosts); 0 = none (the API alone)",
    )
    render_threads: int = Field(0, ge=0, description="threads per worker render; 0 = cores / workers")
    worker_nice: int = Field(10, ge=0, le=19, description="niceness of worker processes, so the API stays responsive")
    kernel_load_gate: Path | None = Field(
        None,
        description="for tests (a slow machine): the start-up's loading of the render kernels, and so the workers' "
        "start, waits until this file exists (10 minutes at most); the page answers meanwhile",
    )
    preview_size: int = Field(160, ge=8, le=1024, description="example scene thumbnails (pixels)")
    previews_ahead: bool = Field(
        True,
        description="render the example scenes' previews at start-up, in the batch lane (off: each when first "
        "asked for)",
    )
    answer_again: bool = Field(
        True,
        description="a render whose result a done render already has (the same scene, renderer and assets) is done "
        "at once with that render's files (server/jobs/results.py)",
    )
    lessons_ahead: bool = Field(
        True,
        description="render the lessons' panels at their first controls at start-up, in the batch lane behind the "
        "previews (server/jobs/lesson_panels.py); needs answer_again",
    )
    preload_mesh_reader: bool = Field(
        True,
        description="import the mesh reader (trimesh, about 0.6 s of CPU and 60 MB) as the render workers, the "
        "scene checkers and the worker hosts start, so that a first scene with a mesh file does not wait for it "
        "(off: each process imports it with its first mesh file; the tests' servers, started by the hundred)",
    )
    preview_interval: float = Field(0.5, ge=0, description="seconds between two published previews of a job")
    poll_interval: float = Field(0.5, gt=0, le=5, description="longest sleep of an idle worker (seconds)")
    job_attempts: int = Field(2, ge=1, le=10, description="tries of a job whose worker died (crash or kill)")
    grading_processes: int = Field(
        0,
        ge=0,
        le=64,
        description="worker processes for grading's per-student work (reading submissions, the image tests); "
        "0 = one per core",
    )

    # Lanes (server/jobs/lifecycle.py): interactive work first; long renders and grading in the batch lane.
    interactive_seconds: float = Field(
        20.0, ge=0, description="renders estimated to take longer than this (seconds) go to the batch lane"
    )
    interactive_workers: int = Field(
        1, ge=0, le=16, description="extra embedded worker processes that take only interactive jobs"
    )
    max_raytree_seconds: float = Field(30.0, gt=0, description="seconds a ray tree may take (its own short job)")
    snapshot_interval: Duration = Field(
        10.0,
        ge=0,
        description="seconds of rendering between two snapshots of a render's film, which a retried "
        "or resumed job continues from (0: after every pass)",
    )
    cache_dir: Path | None = Field(
        None, description="where workers keep radiosity solutions by their scene's content (default DATA/cache)"
    )

    # The job queue (server/queue/base.py): embedded worker processes, or worker hosts through Redis with RQ.
    redis_url: str | None = Field(
        None,
        description="Redis URL (redis://host:6379/0): jobs go to worker hosts (python -m server.worker) through "
        "RQ; unset: the embedded worker processes of this host",
    )
    redis_url_file: Path | None = Field(
        None,
        description="a file whose first line is the Redis URL (with its password), instead of TRACER_REDIS_URL: "
        "never on a command line (ps shows those) nor in the environment",
    )
    lost_after: Duration = Field(
        15.0,
        ge=2,
        le=3600,
        description="Redis backend: seconds without a heartbeat from a try's worker host after which the try is "
        "lost and the job runs again on another host",
    )

    # Housekeeping (server/jobs/janitor.py): finished jobs are removed, rows and folders together.
    keep_finished: Duration = Field(
        7 * 86400.0, ge=0, description="how long a finished job is kept after it ended (90s, 30m, 12h, 7d); 0 = forever"
    )
    max_data_bytes: ByteSize = Field(
        ByteSize(10_000_000_000),
        ge=0,
        description="size cap of the data directory (bytes, or 500MB, 10GB, 2GiB): past it the finished jobs "
        "that ended first are removed; 0 = no cap",
    )
    janitor_interval: Duration = Field(60.0, gt=0, description="time between two rounds of the janitor (seconds)")

    # Who may do what (server/core/security.py): each job belongs to the token that made it.
    instructor_token: SecretStr | None = Field(
        None,
        description="the instructor's bearer token (16 to 512 letters, digits or -._~+/=): grading, and every "
        "job; unset: on a server listening on loopback only everyone is the instructor, elsewhere no one",
    )
    allowed_hosts: str = Field(
        "",
        description="host names the server answers to (the Host header), comma-separated, besides the loopback "
        "names and the address it listens on; '.example.edu' names its subdomains too; '*': any",
    )
    lti_leeway: Duration = Field(
        60.0,
        ge=0,
        le=600,
        description="LTI launches (server/lti/): seconds of clock difference allowed between a platform and this "
        "server when checking an id_token's exp and iat",
    )

    # Limits, each answered with a 4xx (or, for seconds per job, the job failed with that reason).
    max_body_bytes: int = Field(2_000_000, ge=1024, description="request body size (bytes): 413 past it")
    max_json_depth: int = Field(64, ge=4, description="nesting of JSON arrays and objects in a request body")
    max_tree_log_bytes: int = Field(
        4_000_000, ge=1024, description="a student tracer's tree log (POST .../submissions/{sid}/trees): 413 past it"
    )
    max_tree_log_trees: int = Field(64, ge=1, le=64, description="trees in one tree log: 422 past it")
    max_class_entries: int = Field(
        5000, ge=1, description="entries of a class's zip (files and folders), or files uploaded for a class"
    )
    max_class_bytes: ByteSize = Field(
        ByteSize(1_000_000_000),
        ge=1024,
        description="a class's files unpacked, all together (bytes, or 500MB, 1GB); an upload may be this big "
        "plus max_body_bytes (the assignment)",
    )
    max_submissions_per_hour: int = Field(
        20, ge=1, description="submissions of one student to one assignment in any hour: 429 past it"
    )
    max_queued_jobs: int = Field(1000, ge=1, description="jobs waiting in the queue: 429 past it")
    max_queued_per_token: int = Field(
        20, ge=1, description="jobs of one token waiting in the queue (a student's share): 429 past it"
    )
    max_active_jobs_per_token: int = Field(
        16,  # a lesson renders up to 8 panels at once, and its student may have a render of their own going
        ge=1,
        description="renders of one token waiting or running at once, its fair share of the workers (the "
        "instructor's are not counted): 429 past it",
    )
    max_job_seconds: float = Field(600.0, gt=0, description="seconds a job may render before it is stopped, failed")
    # The scene limits (max_width, ... max_solve_rays) are the rows of tracer/limits.py: see SceneLimits.

    # Scene checks (validation, a pixel's samples) run in their own processes, off the API's event loop.
    validate_processes: int = Field(
        2,
        ge=1,
        le=64,
        description="processes that check scenes for POST /api/validate, /api/jobs, /api/raytree and /api/samples",
    )
    max_validate_seconds: float = Field(
        10.0, gt=0, description="seconds of CPU one scene check may take; its process is stopped and replaced past it"
    )
    max_validate_waiting: int = Field(
        2000,  # a class of 1 000 submitting in the same second waits here a few seconds (docs/service.md, "Sizing")
        ge=0,
        description="requests waiting for a free checking process (first come first served): 429 past it",
    )
    max_validate_waiting_bytes: ByteSize = Field(
        ByteSize(256_000_000),  # what the waiting requests' bodies hold in the API's memory: 128 of the largest
        ge=0,
        description="the bodies of the requests waiting for a free checking process, all together (bytes, or 100MB, "
        "1GB): 429 past it",
    )

    # Connections and bodies in flight (issue #24, item 5): slow clients time out, bodies held have a budget.
    header_timeout: Duration = Field(
        10.0, gt=0, description="seconds a request's headers may take, from the connection or its previous answer"
    )
    body_timeout: Duration = Field(
        30.0, gt=0, description="seconds a JSON body may take in all, and any body between two of its chunks: 408"
    )
    max_connections: int = Field(
        2000, ge=1, description="open connections and requests in progress (uvicorn's limit_concurrency): 503 past it"
    )
    max_streams_per_token: int = Field(
        16, ge=1, description="event streams one token may have open at once (the instructor's: any): 429 past it"
    )
    max_streams_per_address: int = Field(
        64,
        ge=1,
        description="event streams one client address may have open at once (times TRACER_SHARED_NETWORK_CLIENTS "
        "in TRACER_SHARED_NETWORKS; at most half of TRACER_MAX_CONNECTIONS, the rest kept for others): 429 past it",
    )
    body_budget_bytes: ByteSize = Field(
        ByteSize(32_000_000),
        ge=0,
        description="bytes of JSON bodies of 64 KB or more held at once, all requests together",
    )
    body_budget_wait: Duration = Field(
        2.0, ge=0, description="seconds a large body waits for the budget before its request is answered 503"
    )

    @model_validator(mode="before")
    @classmethod
    def _redis_url_file(cls, data):
        """TRACER_REDIS_URL_FILE: the URL read from the file, as if TRACER_REDIS_URL had been given."""
        if isinstance(data, dict) and data.get("redis_url_file"):
            url = redis_url_from(None, data["redis_url_file"])
            if data.get("redis_url") not in (None, "", url):  # (settings passed on whole carry the URL read)
                redis_url_from(data["redis_url"], data["redis_url_file"])  # both given: the error that says so
            data = {**data, "redis_url": url}
        return data

    @field_validator("instructor_token", mode="before")
    @classmethod
    def _token(cls, v, info: ValidationInfo):
        """An empty value is no token; any other must be one a client can send as a bearer token."""
        text = v.get_secret_value() if isinstance(v, SecretStr) else v
        if text is None or text == "":
            return None
        if not isinstance(text, str) or not re.fullmatch(r"[A-Za-z0-9._~+/=-]{16,512}", text):
            raise ValueError("the instructor token must be 16 to 512 letters, digits or -._~+/= (a bearer token)")
        weak = weak_token(text)
        host = info.data.get("host", "127.0.0.1")
        if weak and not loopback_address(
            host
        ):  # guessed, it is every student's grade: refused (on loopback: a warning)
            raise ValueError(
                f"the instructor token is too weak for a server listening on {host} ({weak}): use at least "
                f"{MIN_TOKEN_LENGTH} random characters; {STRONG_TOKEN}"
            )
        return text

    @property
    def limits(self) -> Limits:
        """The scene limits, as the tracer's validators take them."""
        return Limits(**{name: getattr(self, name) for name in LIMIT_NAMES})

    def processes_text(self) -> str:
        """What runs beside the API, as /api/health lists it (`workers`, `checkers`), for the start-up log: the
        render workers (embedded: `workers` general ones plus `interactive_workers` that take interactive work
        only, none of either when `workers` is 0, as server/queue/embedded/pool.py starts them; with Redis, the
        local worker hosts), the scene-checking processes, and the grading pool started at the first grading."""

        def n(count: int, noun: str) -> str:
            return f"{count} {noun}{'' if count == 1 else 'es' if noun.endswith('s') else 's'}"

        if self.redis_url:
            renders = f"{n(self.workers, 'local worker host')} on Redis at {masked(self.redis_url)}"
        elif self.workers == 0:
            renders = "no render worker (jobs wait in the queue)"
        else:
            only = f" ({self.interactive_workers} for interactive work only)" if self.interactive_workers else ""
            renders = f"{n(self.workers + self.interactive_workers, 'render worker process')}{only}"
        grading = self.grading_processes or os.cpu_count() or 1
        return (
            f"{renders}, {n(self.validate_processes, 'scene-checking process')}, "
            f"a grading pool of {n(grading, 'process')} from the first grading run"
        )

    def threads_per_worker(self) -> int:
        if self.render_threads:
            return self.render_threads
        return max(1, (os.cpu_count() or 1) // max(1, self.workers))

    # Anonymous clients (server/core/clients.py): what one client address may do without a known identity
    # (the instructor's token, or a token on some assignment's roster), and whether anyone may work without one.
    require_identity: bool = Field(
        False,
        description="jobs, ray trees, validation and samples need a known identity: a token on some assignment's "
        "roster (an open assignment's join gives one) or the instructor's; anyone else gets 401",
    )
    max_new_tokens_per_address: int = Field(
        60,
        ge=1,
        description="tokens issued to one client address (POST /api/jobs without a token, joining an open "
        "assignment) in any TRACER_ADDRESS_WINDOW: 429 past it",
    )
    max_queued_per_address: int = Field(
        40,
        ge=1,
        description="jobs and ray trees waiting in the queue from one client address without a known identity "
        "(a token's own share, TRACER_MAX_QUEUED_PER_TOKEN, holds too): 429 past it",
    )
    address_window: Duration = Field(
        3600.0, gt=0, le=7 * 86400, description="the sliding window of TRACER_MAX_NEW_TOKENS_PER_ADDRESS (90s, 30m, 1h)"
    )
    max_joins_per_address: int = Field(
        20,
        ge=1,
        description="joins of open assignments from one client address in any TRACER_ADDRESS_WINDOW: 429 past it",
    )
    max_joins_per_assignment: int = Field(
        500, ge=1, description="students who joined one open assignment by a name (self-declared): 403 past it"
    )
    max_auth_failures: int = Field(
        20,
        ge=1,
        description="refused tokens (not the instructor's, on no roster where one is needed) from one client "
        "address in TRACER_AUTH_FAILURE_WINDOW, after which its requests with a token get 429",
    )
    auth_failure_window: Duration = Field(
        600.0, gt=0, le=86400, description="the sliding window of TRACER_MAX_AUTH_FAILURES (90s, 10m, 1h)"
    )
    max_checks_per_minute: int = Field(
        30, ge=1, description="checks of a submission (POST /api/assignments/{id}/check) of one token a minute: 429"
    )
    shared_networks: str = Field(
        "",
        description="networks (CIDR, comma-separated: 203.0.113.7/32, 10.0.0.0/8) whose addresses each stand for "
        "many clients, such as a class behind one NAT: their caps are TRACER_SHARED_NETWORK_CLIENTS times one "
        "address's",
    )
    shared_network_clients: int = Field(
        300, ge=1, le=100_000, description="the clients one address of TRACER_SHARED_NETWORKS stands for"
    )

    @field_validator("shared_networks")
    @classmethod
    def _networks(cls, v: str) -> str:
        for part in (p.strip() for p in v.split(",")):
            try:
                if part:
                    ipaddress.ip_network(part, strict=False)
            except ValueError:
                raise ValueError(
                    f"expected networks such as 10.0.0.0/8 or 203.0.113.7, comma-separated; got {part[:80]!r}"
                ) from None
        return v


def load_settings(settings_file: str | os.PathLike | None = None, **overrides) -> Settings:
    """Settings from `overrides`, the environment and a settings file (argument or TRACER_SETTINGS_FILE)."""
    settings_file = settings_file or os.environ.get("TRACER_SETTINGS_FILE") or None
    if settings_file is not None and not Path(settings_file).is_file():
        raise FileNotFoundError(f"settings file not found: {settings_file}")
    # pydantic-settings' own __init__ argument, which pyright's model of a pydantic class (its fields) leaves out
    return Settings(_env_file=settings_file, **overrides)  # pyright: ignore[reportCallIssue]


def explain(exc: ValidationError, flags: dict[str, str] | None = None) -> str:
    """pydantic's errors as one line per setting, named as the user gave it (`flags`: field -> the command
    line's option that set it; else its TRACER_ variable) with what was expected; never the value (a token)."""
    lines = []
    for e in exc.errors():
        field = str(e["loc"][0]) if e["loc"] else ""
        name = (flags or {}).get(field) or f"TRACER_{field.upper()}"
        message = e["msg"].removeprefix("Value error, ")
        lines.append(f"{name}: {message}" if field else message)  # a check of several settings names them
    return "; ".join(lines)
