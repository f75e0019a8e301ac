"""Validation, the JSON Schema, the ray tree of one pixel, and health."""

from __future__ import annotations

from fastapi import APIRouter

from server.deps import QueueDep, SettingsDep, StoreDep
from server.errors import ApiError
from server.models import ErrorResponse, Health, RayTreeRequest, ValidateRequest
from server.routes.jobs import check_scene
from tracer.compile import compile_scene
from tracer.raytree import ray_tree
from tracer.scene import SceneError, scene_json_schema

router = APIRouter(prefix="/api", tags=["tools"])


@router.get("/health", summary="Liveness, the render workers (pids) and the jobs by status")
def health(store: StoreDep, queue: QueueDep) -> Health:
    return Health(status="ok", backend=queue.backend, workers=queue.workers(), jobs=store.counts())


@router.get("/schema", summary="The scene format's JSON Schema (for editors)")
def schema() -> dict:
    return scene_json_schema()


@router.post("/validate", summary="Check a scene: errors with JSON paths, and warnings")
def validate(body: ValidateRequest, settings: SettingsDep) -> dict:
    """`valid` is true when POST /api/jobs would accept the scene: the format, the service limits,
    and the asset files are all checked."""
    try:
        _, warnings = check_scene(body.scene, settings)
    except ApiError as exc:
        return {"valid": False, "errors": exc.errors, "warnings": []}
    return {"valid": True, "errors": [], "warnings": warnings}


@router.post(
    "/raytree",
    summary="The ray tree of one pixel sample (/reference/scene-format.md#the-ray-tree)",
    responses={422: {"model": ErrorResponse, "description": "invalid scene, or x, y, sample out of range"}},
)
def raytree(body: RayTreeRequest, settings: SettingsDep) -> dict:
    scene, _ = check_scene(body.scene, settings)
    try:
        return ray_tree(compile_scene(scene), body.x, body.y, body.sample)
    except SceneError as exc:
        raise ApiError(422, exc.errors) from None
