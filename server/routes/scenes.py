"""Example scenes: the list, one scene's JSON, and a small preview render of it."""

from __future__ import annotations

import json
import threading
from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import Response

from server.deps import SettingsDep
from server.errors import ApiError
from server.store import write_atomic
from tracer.compile import compile_scene
from tracer.film import png_bytes
from tracer.render import render
from tracer.scene import SceneError, load_scene

SCENES = Path(__file__).resolve().parent.parent.parent / "scenes"
router = APIRouter(prefix="/api/scenes", tags=["scenes"])
_render_lock = threading.Lock()  # one preview render at a time, in the API process (cached on disk after)


def _path(name: str) -> Path:
    p = SCENES / f"{name}.json"
    if not name.replace("_", "").replace("-", "").isalnum() or not p.is_file():
        raise ApiError(404, [{"path": "name", "message": f"no example scene named '{name[:64]}'"}])
    return p


@router.get("", summary="The example scenes, one per lecture topic")
def list_scenes() -> list[dict]:
    out = []
    for p in sorted(SCENES.glob("*.json")):
        data = json.loads(p.read_text())
        out.append({"name": p.stem, "title": data.get("name") or p.stem, "description": data.get("description", "")})
    return out


@router.get("/{name}", summary="One example scene's JSON")
def get_scene(name: str) -> dict:
    return json.loads(_path(name).read_text())


@router.get(
    "/{name}/preview.png",
    summary="A small render of an example scene (cached on disk)",
    response_class=Response,
    responses={200: {"content": {"image/png": {}}}},
)
def preview(name: str, settings: SettingsDep) -> Response:
    src = _path(name)
    cache = settings.data_dir / "previews" / f"{name}-{settings.preview_size}-{int(src.stat().st_mtime)}.png"
    if not cache.is_file():
        data = json.loads(src.read_text())
        w, h = data.get("film", {}).get("width", 256), data.get("film", {}).get("height", 256)
        scale = settings.preview_size / max(w, h)
        data.setdefault("film", {}).update(width=max(1, round(w * scale)), height=max(1, round(h * scale)))
        try:
            scene, _ = load_scene(data)
            compiled = compile_scene(scene)
        except SceneError as exc:  # an example using a feature this renderer does not have yet
            raise ApiError(422, exc.errors) from None
        with _render_lock:  # one thread: the API's own core stays free for requests
            result = render(compiled, threads=1)
        png = png_bytes(result.image, scene.film.exposure)
        write_atomic(cache, lambda tmp: tmp.write_bytes(png))
    return Response(cache.read_bytes(), media_type="image/png")
