"""The entry points: a scene from a dict, JSON text or a file's path, validated with every error at its
JSON path (`load_scene`, `validate_scene`), and the JSON Schema of the format (`scene_json_schema`)."""

import json
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from tracer.errors import SceneError, pydantic_errors, show_value
from tracer.limits import Limits
from tracer.scene.lint import _warnings
from tracer.scene.model import Scene


def _scene_file(text: str) -> Path | None:
    """The text as the path of an existing file, or None (it is not one, or cannot be one)."""
    if "\n" in text or len(text) > 4096:
        return None
    try:
        path = Path(text)
        return path if path.is_file() else None
    except (OSError, ValueError):  # a NUL byte, a name too long
        return None


def _not_json(text: str, e: json.JSONDecodeError) -> str:
    """Why a text that is not JSON is not a scene either (it is no file's path)."""
    where = f"line {e.lineno}, column {e.colno}"
    if not text.strip():
        return "the scene text is empty: expected JSON {...} or the path of a scene file"
    if text.lstrip()[:1] in ("{", "["):
        return f"invalid JSON at {where}: {e.msg}"
    if "\n" not in text and (text.strip().lower().endswith(".json") or "/" in text or "\\" in text):
        return f"cannot read scene file {text}: no such file (and the text is not JSON either)"
    shown = text.strip()[:40] + ("..." if len(text.strip()) > 40 else "")
    return f"'{shown}' is neither JSON (invalid JSON at {where}: {e.msg}) nor the path of a scene file"


def _parse(src: Any) -> dict:
    """dict, JSON text (str or bytes), or a scene file's path (Path or str) -> the scene dict."""
    if isinstance(src, str) and src.lstrip()[:1] not in ("{", "["):
        src = _scene_file(src) or src  # "scenes/cornell.json" is a path; '{"camera": ...}' is JSON
    if isinstance(src, Path):
        try:
            src = src.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise SceneError([{"path": "", "message": f"cannot read scene file {src}: {e}"}]) from None
    if isinstance(src, bytes | bytearray):
        try:
            src = src.decode("utf-8")
        except UnicodeDecodeError as e:
            raise SceneError([{"path": "", "message": f"scene is not UTF-8 text: {e}"}]) from None
    if isinstance(src, str):
        try:
            src = json.loads(src)
        except json.JSONDecodeError as e:
            raise SceneError([{"path": "", "message": _not_json(src, e)}]) from None
        except (ValueError, RecursionError) as e:  # e.g. an integer of more than 4300 digits
            raise SceneError([{"path": "", "message": f"invalid JSON: {e}"}]) from None
    if not isinstance(src, dict):
        raise SceneError([{"path": "", "message": f"a scene must be a JSON object {{...}}, got {show_value(src)}"}])
    return src


def load_scene(
    src: Any, limits: Limits | None = None, assets: Path | str | None = None
) -> tuple[Scene, list[dict[str, str]]]:
    """Parse and validate a scene: (Scene, warnings). Raises SceneError listing every error.

    `src`: a dict, JSON text (str or bytes), or the path of a scene file (Path or str).
    `assets`: the asset folder (ASSET_DIR is the default one) to resolve the scene's files in, so that
    a missing or unreadable mesh or image, a data: URI that is not one, and the triangles of mesh files
    past `limits.max_primitives` are errors here too, at their JSON paths. None checks the format
    only (the renderer reads the files, and says what is wrong with them, when it compiles the scene).
    """
    data = _parse(src)
    materials = data.get("materials")
    context = {
        "limits": limits or Limits(),
        "material_names": set(materials) if isinstance(materials, dict) else None,
        "assets": None if assets is None else Path(assets),
    }
    try:
        scene = Scene.model_validate(data, context=context)
    except ValidationError as e:
        raise SceneError(pydantic_errors(e, Scene)) from None
    return scene, _warnings(scene)


def validate_scene(src: Any, limits: Limits | None = None, assets: Path | str | None = None) -> dict:
    """{"valid": bool, "errors": [...], "warnings": [...]}; never raises for a bad scene.

    With `assets` (a folder, see `load_scene`) the scene's files are resolved and checked too."""
    try:
        _, warnings = load_scene(src, limits, assets)
    except SceneError as e:
        return {"valid": False, "errors": e.errors, "warnings": []}
    return {"valid": True, "errors": [], "warnings": warnings}


def scene_json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a scene, generated from the models, with descriptions."""
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **Scene.model_json_schema()}
