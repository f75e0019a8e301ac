"""Where the renderer puts one pixel's samples (the page's sampler pictures): POST /api/samples."""

from __future__ import annotations

from typing import ClassVar

from fastapi import APIRouter
from pydantic import Field, StrictInt

from server.deps import SettingsDep
from server.errors import ApiError
from server.models import ErrorResponse, _SceneRequest
from server.routes.jobs import check_scene
from tracer.compile import compile_scene
from tracer.samples import pixel_samples
from tracer.scene import SceneError

router = APIRouter(prefix="/api", tags=["tools"])


class SamplesRequest(_SceneRequest):
    EXAMPLE: ClassVar[str] = '{"scene": {...}, "x": 10, "y": 20}'

    x: StrictInt = Field(description="pixel column from the left")
    y: StrictInt = Field(description="pixel row from the top")


@router.post(
    "/samples",
    summary="Where the renderer puts the samples of one pixel (the sampler's positions)",
    responses={422: {"model": ErrorResponse, "description": "invalid scene, x or y off the film, too many samples"}},
)
def samples(body: SamplesRequest, settings: SettingsDep) -> dict:
    """The film positions of the eye rays of pixel (x, y), computed by the renderer's own sampling code:
    sample k's eye ray passes through film point (x + u, y + v), `position` = [u, v] (docs/web.md,
    "Sample positions"). The adaptive sampler lists every point of its grid levels, whether this
    pixel's subdivision traced it, and the cells it visited."""
    scene, _ = check_scene(body.scene, settings)
    try:
        # as many positions as a scene may have samples (the service's max_spp), the adaptive grid's included
        return pixel_samples(compile_scene(scene), body.x, body.y, max_samples=settings.limits.max_spp)
    except SceneError as exc:
        raise ApiError(422, exc.errors) from None
