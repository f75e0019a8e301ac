"""Example scenes: the list (with the state of each one's preview), one scene's JSON, and its preview.

The previews are rendered by the workers (server/jobs/previews.py), never in the API process: at start-up, or
the first time one is asked for."""

from __future__ import annotations

import json
from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse

from server.api.deps import PreviewsDep
from server.api.errors import ApiError
from server.core.paths import SCENES

router = APIRouter(prefix="/api/scenes", tags=["scenes"])


def _path(name: str) -> Path:
    p = SCENES / f"{name}.json"
    if not name.replace("_", "").replace("-", "").isalnum() or not p.is_file():
        raise ApiError(404, [{"path": "name", "message": f"no example scene named '{name[:64]}'"}])
    return p


@router.get("", summary="The example scenes, one per lecture topic, and the state of their previews")
def list_scenes(previews: PreviewsDep) -> list[dict]:
    out = []
    for p in sorted(SCENES.glob("*.json")):
        data = json.loads(p.read_text())
        out.append({
            "name": p.stem, "title": data.get("name") or p.stem, "description": data.get("description", ""),
            "preview": previews.state(p.stem),
        })  # fmt: skip
    return out


@router.get("/{name}", summary="One example scene's JSON")
def get_scene(name: str) -> dict:
    return json.loads(_path(name).read_text())


@router.post("/{name}/preview", status_code=202, summary="Ask for an example's preview: queued unless it is made")
def ask_preview(name: str, previews: PreviewsDep) -> dict:
    """The preview's state (as in GET /api/scenes), its render queued first when nothing made or queued it
    (a server that does not render the previews ahead)."""
    _path(name)
    previews.ensure(name)
    return previews.state(name)


@router.get(
    "/{name}/preview.png",
    summary="A small render of an example scene, made by a render worker",
    response_class=FileResponse,
    responses={200: {"content": {"image/png": {}}}, 503: {"description": "not rendered yet (Retry-After)"}},
)
def preview(name: str, previews: PreviewsDep) -> FileResponse:
    _path(name)
    png = previews.file(name)
    if png is None:
        previews.ensure(name)  # queued now when the server did not render previews ahead
        state = previews.state(name)
        words = {"queued": "waits for a render worker", "rendering": "is being rendered", "none": "waits"}
        if state["state"] == "failed":
            raise ApiError(422, [{"path": "name", "message": f"the preview of '{name}' failed: {state['error']}"}])
        message = f"the preview of '{name}' {words.get(state['state'], 'is on its way')}; try again in a moment"
        raise ApiError(503, [{"path": "name", "message": message}], headers={"Retry-After": "2"})
    return FileResponse(png, media_type="image/png", headers={"Cache-Control": "no-cache"})
