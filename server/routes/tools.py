"""Validation, the JSON Schema, the ray tree of one pixel, and health."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

from tracer.compile import compile_scene
from tracer.raytree import ray_tree
from tracer.scene import SceneError, load_scene, scene_json_schema, validate_scene

router = APIRouter(prefix="/api", tags=["tools"])


class ValidateRequest(BaseModel):
    scene: Any = Field(description="a scene object (SCENE_FORMAT.md)")


class RayTreeRequest(BaseModel):
    scene: Any = Field(description="a scene object (SCENE_FORMAT.md)")
    x: int = Field(description="pixel column from the left")
    y: int = Field(description="pixel row from the top")
    sample: int = Field(0, description="sample index within the pixel")


def errors_response(errors: list[dict], status: int = 422) -> JSONResponse:
    return JSONResponse({"errors": errors}, status_code=status)


@router.get("/health", summary="Liveness")
def health() -> dict:
    return {"status": "ok"}


@router.get("/schema", summary="The scene format's JSON Schema (for editors)")
def schema() -> dict:
    return scene_json_schema()


@router.post("/validate", summary="Check a scene: errors with JSON paths, and warnings")
def validate(body: ValidateRequest, request: Request) -> dict:
    return validate_scene(body.scene, request.app.state.settings.limits)


@router.post("/raytree", summary="The ray tree of one pixel sample (SCENE_FORMAT.md, 'Ray tree')")
def raytree(body: RayTreeRequest, request: Request):
    try:
        scene, _ = load_scene(body.scene, request.app.state.settings.limits)
        return ray_tree(compile_scene(scene), body.x, body.y, body.sample)
    except SceneError as exc:
        return errors_response(exc.errors)
