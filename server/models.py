"""The API's data: job status, what a client sends (Create) and what it gets back (Public)."""

from __future__ import annotations

import json
import time
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, StrictInt


class JobStatus(StrEnum):
    queued = "queued"  # waiting for a worker, by priority then age
    running = "running"  # a worker is rendering it
    done = "done"  # all samples rendered; the final image is kept
    failed = "failed"  # invalid at render time, over its time limit, or its worker died too often
    cancelled = "cancelled"  # DELETE /api/jobs/{id}; a running job keeps its last image

    @property
    def finished(self) -> bool:
        return self in (JobStatus.done, JobStatus.failed, JobStatus.cancelled)


class ErrorItem(BaseModel):
    path: str = Field(description="JSON path of the offending field ('' for the whole request)")
    message: str


class ErrorResponse(BaseModel):
    errors: list[ErrorItem]


SCENE_DESCRIPTION = "a scene object (the format: /reference/scene-format.md); its JSON Schema is at GET /api/schema"


class JobCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    scene: dict[str, Any] = Field(description=SCENE_DESCRIPTION)
    priority: StrictInt = Field(0, ge=-100, le=100, description="higher runs first; then first come, first served")


class ValidateRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    scene: dict[str, Any] = Field(description=SCENE_DESCRIPTION)


class RayTreeRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    scene: dict[str, Any] = Field(description=SCENE_DESCRIPTION)
    x: StrictInt = Field(description="pixel column from the left")
    y: StrictInt = Field(description="pixel row from the top")
    sample: StrictInt = Field(0, description="sample index within the pixel")


class JobProgress(BaseModel):
    samples_done: int = Field(description="pixel samples rendered (adaptive sampler: pixels x passes)")
    samples_total: int = Field(description="width x height x spp (adaptive sampler: pixels x levels)")
    fraction: float = Field(description="samples_done / samples_total, 0..1")
    passes_done: int = Field(description="progressive passes finished (1, 1, 2, 4, ... samples per pixel each)")
    spp_done: int = Field(description="samples per pixel in the latest image")
    spp_total: int = Field(description="samples per pixel asked for")


class JobPublic(BaseModel):
    id: str = Field(description="unguessable job id")
    status: JobStatus
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
    rays: dict[str, int] = Field(description="rays traced by kind (eye, shadow, reflection, transmission) and total")
    preview: int = Field(description="number of the pass in the latest image; 0 = no image yet")
    image_url: str | None = Field(description="the latest PNG (add ?format=exr for linear float EXR)")
    events_url: str = Field(description="Server-Sent Events: progress, preview, end")
    error: str | None = Field(description="why the job failed (or how it was stopped)")
    errors: list[ErrorItem] = Field(description="scene errors found at render time (a missing asset), with paths")
    warnings: list[ErrorItem] = Field(description="settings in the scene that have no effect")
    attempts: int = Field(description="times a worker took the job (more than 1 after a worker died)")
    cancel_requested: bool

    @classmethod
    def from_row(cls, row: dict, now: float | None = None) -> JobPublic:
        now = time.time() if now is None else now
        status = JobStatus(row["status"])
        total = row["samples_total"]
        done = row["samples_done"]
        fraction = done / total if total else 0.0
        elapsed = eta = None
        if row["started_at"] is not None:
            end = row["finished_at"] if row["finished_at"] is not None else now
            elapsed = max(0.0, end - row["started_at"])
            if status is JobStatus.running and done > 0:
                eta = elapsed * (1.0 - fraction) / fraction
        preview = row["preview"]
        return cls(
            id=row["id"],
            status=status,
            priority=row["priority"],
            name=row["name"],
            width=row["width"],
            height=row["height"],
            created_at=_dt(row["created_at"]),
            started_at=_dt(row["started_at"]),
            finished_at=_dt(row["finished_at"]),
            progress=JobProgress(
                samples_done=done,
                samples_total=total,
                fraction=round(fraction, 6),
                passes_done=row["passes_done"],
                spp_done=row["spp_done"],
                spp_total=row["spp"],
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
            cancel_requested=bool(row["cancel_requested"]),
        )


def _dt(t: float | None) -> datetime | None:
    return None if t is None else datetime.fromtimestamp(t, UTC)


class JobList(BaseModel):
    jobs: list[JobPublic] = Field(description="newest first")
    count: int = Field(description="jobs that match, in all")


class WorkerInfo(BaseModel):
    slot: int
    pid: int | None = Field(description="process id of the worker (the crash test kills it)")
    alive: bool
    ready: bool = Field(description="kernels loaded, taking jobs")
    restarts: int
    job: str | None = Field(description="id of the job it renders")


class Health(BaseModel):
    status: str = Field(description="'ok'")
    workers: list[WorkerInfo]
    jobs: dict[str, int] = Field(description="jobs by status")
