"""Where the renderer puts one pixel's samples (the page's sampler pictures): POST /api/samples."""

from __future__ import annotations

from typing import ClassVar

from fastapi import APIRouter, Depends, Request
from pydantic import Field, StrictInt

from server.api.deps import ChecksDep, get_client
from server.api.models import ErrorResponse, _SceneRequest
from server.api.scene_route import scene_post

router = APIRouter(prefix="/api", tags=["tools"])


class SamplesRequest(_SceneRequest):
    EXAMPLE: ClassVar[str] = '{"scene": {...}, "x": 10, "y": 20}'

    x: StrictInt = Field(description="pixel column from the left")
    y: StrictInt = Field(description="pixel row from the top")


@scene_post(
    router,
    "/samples",
    summary="Where the renderer puts the samples of one pixel (the sampler's positions)",
    dependencies=[Depends(get_client)],  # TRACER_REQUIRE_IDENTITY: a known identity, else 401
    responses={
        401: {"model": ErrorResponse, "description": "TRACER_REQUIRE_IDENTITY, and no known identity"},
        422: {"model": ErrorResponse, "description": "invalid scene, x or y off the film, too many samples"},
    },
)
async def samples(body: SamplesRequest, checks: ChecksDep, request: Request) -> dict:
    """The film positions of the eye rays of pixel (x, y), computed by the renderer's own sampling code:
    sample k's eye ray passes through film point (x + u, y + v), `position` = [u, v] (docs/web.md,
    "Sample positions"). The adaptive sampler lists every point of its grid levels, whether this
    pixel's subdivision traced it, and the cells it visited. Computed in a checking process
    (server/checkers/pool.py), never in the API process."""
    return await checks.samples(request.is_disconnected, await request.body(), body.x, body.y)
