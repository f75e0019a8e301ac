"""A job as clients see it (GET /api/jobs/{id}, the event streams, the lists): its status, progress, ETA,
tries and place in the queue, built from its row in one place (`JobPublic.from_row`)."""

from __future__ import annotations

import json
import time
from datetime import UTC, datetime

from pydantic import BaseModel, Field

from server.core.errors import ErrorItem
from server.jobs.lifecycle import JobKind, JobStatus, Lane
from server.jobs.rows import JobRow


class SolveProgress(BaseModel):
    fraction: float = Field(
        description="how far the solve is, 0..1 (shots against max_steps, or the unshot power's fall)"
    )
    shots: int = Field(description="shots so far (a light or a patch shooting its unshot power)")
    rays: int = Field(description="rays cast by the solve so far")
    seconds: float = Field(description="seconds spent solving")
    unshot: float = Field(description="share of the emitted power not shot yet, 0..1")
    patches: int = Field(description="patch sides of the solution (two per piece of surface)")
    cached: bool = Field(False, description="read from the workers' cache of solutions (the same scene solved before)")


class TryInfo(BaseModel):
    attempt: int = Field(description="the try's number, from 1")
    host: str | None = Field(description="the worker host that ran it")
    device: str | None = Field(description="cpu, or a GPU such as cuda:0")
    worker: int | str | None = Field(description="the worker: a process id here, or a worker host's name")
    started_at: float = Field(description="Unix time the try started")
    ended_at: float | None = Field(description="Unix time it ended; null while it runs")
    outcome: str | None = Field(
        description="done, failed, cancelled, 'lost' (its worker died or its host was cut off), "
        "'given back' (its host shut down), 'gave way' (to interactive work); null while it runs"
    )
    resumed_from: int | None = Field(None, description="the pass it continued from (0: from the start)")


class JobProgress(BaseModel):
    samples_done: int = Field(description="pixel samples rendered (adaptive sampler: pixels x passes)")
    samples_total: int = Field(description="width x height x spp (adaptive sampler: pixels x levels)")
    fraction: float = Field(description="samples_done / samples_total, 0..1")
    passes_done: int = Field(description="progressive passes finished (1, 1, 2, 4, ... samples per pixel each)")
    spp_done: int = Field(description="samples per pixel in the latest image")
    spp_total: int = Field(description="samples per pixel asked for")
    phase: str = Field(
        description="what the job is doing: 'queued', 'radiosity' (solving the radiosity solution, before any "
        "pass), 'render' (the passes), or 'finished'"
    )
    solve: SolveProgress | None = Field(description="the radiosity solve, for the radiosity integrator; else null")


class QueuePlace(BaseModel):
    lane: Lane = Field(description="interactive jobs are taken before batch ones")
    position: int = Field(description="1: the next job a worker of its lane takes")
    ahead: int = Field(description="queued jobs that will start before it")
    running: int = Field(description="jobs running now")
    workers: int = Field(description="workers that take jobs of its lane")
    expected_wait: float | None = Field(
        description="seconds until it starts, estimated from the renders ahead of it (null: no worker takes its lane)"
    )


class JobPublic(BaseModel):
    id: str = Field(description="unguessable job id")
    status: JobStatus
    finished: bool = Field(description="true once the job has ended (done, failed or cancelled): nothing changes after")
    priority: int
    name: str | None = Field(description="the scene's name, if it has one")
    width: int
    height: int
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    progress: JobProgress
    elapsed: float | None = Field(description="seconds since a worker took the job (until it ended)")
    eta: float | None = Field(description="seconds left, estimated from the samples done so far")
    rays: dict[str, int] = Field(
        description="rays traced by kind (eye, shadow, reflection, transmission; radiosity: the solve's) and total"
    )
    preview: int = Field(description="number of the pass in the latest image; 0 = no image yet")
    image_url: str | None = Field(description="the latest PNG (add ?format=exr for linear float EXR)")
    events_url: str = Field(description="Server-Sent Events: progress, preview, end")
    error: str | None = Field(description="why the job failed (or how it was stopped)")
    errors: list[ErrorItem] = Field(description="scene errors found at render time (a missing asset), with paths")
    warnings: list[ErrorItem] = Field(description="settings in the scene that have no effect")
    attempts: int = Field(
        description="the job's try: times a worker took it (more than 1 after its worker died, or its host was "
        "lost or gave it back)"
    )
    tries: list[TryInfo] = Field(description="each try, oldest first: where it ran and how it ended")
    kind: JobKind = Field(
        description="render, raytree (the short job behind POST /api/raytree), or preview (an example's picture)"
    )
    lane: Lane = Field(description="interactive or batch")
    estimate: float | None = Field(description="seconds the render was estimated to take, at submit")
    queue: QueuePlace | None = Field(
        default=None, description="a queued job's place in the queue and its expected wait"
    )
    snapshot: int = Field(
        description="the pass of the film last saved: a try that takes the job (after a lost worker, or a render "
        "that gave way to interactive work) continues from it; 0: none"
    )
    host: str | None = Field(description="the worker host of the latest try")
    device: str | None = Field(description="the device of the latest try: cpu, or a GPU such as cuda:0")
    cancel_requested: bool

    @classmethod
    def from_row(cls, row: JobRow, now: float | None = None) -> JobPublic:
        now = time.time() if now is None else now
        status = JobStatus(row["status"])
        total = row["samples_total"]
        done = row["samples_done"]
        fraction = done / total if total else 0.0
        solve_json = row.get("solve")
        solve = json.loads(solve_json) if solve_json else None
        solving = status is JobStatus.running and solve is not None and solve.get("fraction", 1.0) < 1.0 and done == 0
        phase = "finished" if status.finished else "queued" if status is JobStatus.queued else "render"
        phase = "radiosity" if solving else phase
        elapsed = eta = None
        if row["started_at"] is not None:
            end = row["finished_at"] if row["finished_at"] is not None else now
            elapsed = max(0.0, end - row["started_at"])
            rendering = max(0.0, elapsed - (solve or {}).get("seconds", 0.0))  # the passes' own time
            if status is JobStatus.running and done > 0:
                eta = rendering * (1.0 - fraction) / fraction
            elif solving and solve is not None and solve["fraction"] > 0:
                eta = elapsed * (1.0 - solve["fraction"]) / solve["fraction"]  # of the solve
        preview = row["preview"]
        return cls(
            id=row["id"],
            status=status,
            finished=status.finished,
            priority=row["priority"],
            name=row["name"],
            width=row["width"],
            height=row["height"],
            created_at=datetime.fromtimestamp(row["created_at"], UTC),  # (NOT NULL)
            started_at=_dt(row["started_at"]),
            finished_at=_dt(row["finished_at"]),
            progress=JobProgress(
                samples_done=done,
                samples_total=total,
                fraction=round(fraction, 6),
                passes_done=row["passes_done"],
                spp_done=row["spp_done"],
                spp_total=row["spp"],
                phase=phase,
                solve=solve,
            ),
            elapsed=elapsed,
            eta=eta,
            rays=json.loads(row["rays"]),
            preview=preview,
            image_url=f"/api/jobs/{row['id']}/image?pass={preview}" if preview else None,
            events_url=f"/api/jobs/{row['id']}/events",
            error=row["error"],
            errors=json.loads(row["errors"]),
            warnings=json.loads(row["warnings"]),
            attempts=row["attempts"],
            tries=json.loads(row.get("tries") or "[]"),
            kind=JobKind(row.get("kind") or JobKind.render),
            lane=Lane(row.get("lane") or Lane.interactive),
            estimate=row.get("estimate"),
            snapshot=row.get("snapshot") or 0,
            host=row.get("host"),
            device=row.get("device"),
            cancel_requested=bool(row["cancel_requested"]),
        )


def _dt(t: float | None) -> datetime | None:
    return None if t is None else datetime.fromtimestamp(t, UTC)
