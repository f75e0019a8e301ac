"""The API's data: what a client sends (Create) and what it gets back (Public).
Job statuses: server/jobs/lifecycle.py."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictInt, model_validator
from pydantic_core import PydanticCustomError

from server.core.errors import ErrorItem
from server.jobs.lifecycle import Lane
from server.jobs.views import JobPublic
from tracer.scene import Scene


class ErrorResponse(BaseModel):
    errors: list[ErrorItem]


# a route's documented answers (FastAPI's `responses=`): status code -> {"model": ..., "description": ...}
Responses = dict[int | str, dict[str, Any]]


SCENE_DESCRIPTION = "a scene object (the format: /reference/scene-format.md); its JSON Schema is at GET /api/schema"


class _SceneRequest(BaseModel):
    """A request that carries a scene under "scene"; a bare scene posted instead gets one hint, not an
    "unknown field" error for each of its keys."""

    model_config = ConfigDict(extra="forbid")
    EXAMPLE: ClassVar[str] = '{"scene": {...}}'

    scene: dict[str, Any] = Field(description=SCENE_DESCRIPTION)

    @model_validator(mode="before")
    @classmethod
    def _bare_scene(cls, data: Any) -> Any:
        if isinstance(data, dict) and "scene" not in data:
            telling = ["camera", "objects", "lights", "materials", *Scene.model_fields]  # the first ones named
            keys = [k for k in dict.fromkeys(telling) if k in data]
            if keys:
                shown = ", ".join(keys[:3]) + (", ..." if len(keys) > 3 else "")
                raise PydanticCustomError(
                    "bare_scene",
                    "the scene must be sent inside the request as {example}; this body has the scene's own "
                    "fields ({shown}) at its top level",
                    {"example": cls.EXAMPLE, "shown": shown},
                )
        return data


class JobCreate(_SceneRequest):
    EXAMPLE: ClassVar[str] = '{"scene": {...}, "priority": 0}'

    priority: StrictInt = Field(
        0,
        ge=-100,
        le=100,
        description="higher runs first; then first come, first served. Above 0 is the instructor's: anyone else's "
        "is lowered to 0, with a warning at `priority`",
    )
    lane: Lane | None = Field(
        None,
        description="batch: move the job down to the batch lane; interactive: the instructor's only (anyone else's "
        "render estimated past TRACER_INTERACTIVE_SECONDS goes to the batch lane, with a warning at `lane`); null: "
        "interactive unless the render is estimated to take longer than TRACER_INTERACTIVE_SECONDS",
    )


class ValidateRequest(_SceneRequest):
    pass


class RayTreeRequest(_SceneRequest):
    EXAMPLE: ClassVar[str] = '{"scene": {...}, "x": 10, "y": 20}'

    x: StrictInt = Field(description="pixel column from the left")
    y: StrictInt = Field(description="pixel row from the top")
    sample: StrictInt = Field(0, description="sample index within the pixel")


class JobCreated(JobPublic):
    token: str | None = Field(
        None,
        description="the token that owns the job, issued when the request sent none: send it as "
        "'Authorization: Bearer <token>' to read, follow, cancel or download this job and to submit the next "
        "ones (null when the request sent its own)",
    )


class JobList(BaseModel):
    jobs: list[JobPublic] = Field(description="newest first")
    count: int = Field(description="jobs that match, in all")


class WorkerInfo(BaseModel):
    slot: int = Field(description="the worker's place in the list")
    name: str | None = Field(None, description="a worker host's name (the Redis backend)")
    host: str | None = Field(None, description="the machine it runs on")
    device: str | None = Field(None, description="cpu, or a GPU such as cuda:0")
    threads: int | None = Field(None, description="render threads of a worker host")
    pid: int | None = Field(description="process id of the worker (the crash test kills it)")
    alive: bool
    ready: bool = Field(description="kernels loaded, taking jobs")
    restarts: int
    job: str | None = Field(description="id of the job it renders")
    lanes: list[str] = Field(["interactive", "batch"], description="the lanes it takes jobs from, in order")


class Health(BaseModel):
    status: str = Field(
        description="'ok', or 'starting' while the render kernels load or a worker is still loading them (a render "
        "submitted meanwhile waits in the queue)"
    )
    backend: str = Field(description="the job queue: 'embedded' (workers on this host) or 'redis' (worker hosts)")
    queue: dict[str, int] = Field(
        default_factory=dict,
        description="the Redis backend's counts since the API started: events applied, stale (reports of tries "
        "that had lost their job, dropped), lost (tries lost with their host), bytes (files received)",
    )
    workers: list[WorkerInfo]
    checkers: list[dict] = Field(
        default_factory=list,
        description="the processes that check scenes (server/checkers/): pid, state (starting, idle, busy), task "
        "(while busy: read, validate, summary, samples), restarts",
    )
    jobs: dict[str, int] = Field(description="jobs by status")
    followers: int = Field(
        0, description="what follows a job now: open event streams, and requests that wait for a ray tree"
    )
    grading: dict[str, float | int | None] = Field(
        default_factory=dict,
        description="grading runs: waiting_for_space, how many wait for space on the disk (each goes on once there "
        "is some: the janitor's round or a new submission wakes it), and since when (Unix time; null if none)",
    )


class HandedIn(BaseModel):
    """A student's work as it is handed in: a scene, or an image of the reference scene from their own
    ray tracer (exactly one of the two)."""

    model_config = ConfigDict(extra="forbid")

    scene: dict[str, Any] | str | None = Field(None, description="a scene object, or its JSON text (may be broken)")
    image: str | None = Field(None, description="a PNG or EXR image of the reference scene, base64")
    format: Literal["png", "exr"] = Field("png", description="the image's format")

    @model_validator(mode="after")
    def _one(self) -> HandedIn:
        if (self.scene is None) == (self.image is None):
            raise ValueError("give exactly one of 'scene' and 'image'")
        return self


class CheckIn(HandedIn):
    """What the check takes: a submission's body, and with an image, the tree log of your own tracer."""

    trees: dict[str, Any] | None = Field(
        None, description="your tracer's tree log (docs/own-tracer.md): each tree compared with the reference's"
    )
