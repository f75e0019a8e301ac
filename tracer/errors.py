"""Errors as a list of {path, message}: the SceneError every check raises, and the one translation of
pydantic's validation errors into that shape (the scene format, the assignment spec, the API's requests).

`pydantic_errors(exc, root)` puts each error at the JSON path of the offending value inside `root`
(`objects[3].radius`; the tags of tagged unions, the member names of plain unions and validator
labels that pydantic puts in its locations dropped) with a message a student can act on: "unknown
field 'radus'; did you mean 'radius'?", "expected one of: whitted, path, radiosity; got ...".
"""

from __future__ import annotations

import difflib
import json
import re
from collections.abc import Mapping
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, Tag, ValidationError

FLOAT32_MAX = 3.4028234663852886e38  # the renderer computes in 32-bit floats
FINITE = "must be a finite number (not NaN or Infinity)"
FLOAT32 = "must be between -3.4e38 and 3.4e38 (the renderer computes in 32-bit floats)"


class Cancelled(Exception):
    """A radiosity solve was asked to stop (its `cancel()` returned True between two shots)."""


class SceneError(Exception):
    """An invalid scene; `errors` is a list of {"path": "objects[3].radius", "message": ...} (a JSON syntax
    error's also has "at": its (line, column))."""

    def __init__(self, errors: list[dict[str, Any]]):
        self.errors = list(errors)
        super().__init__("\n".join(f"{e['path']}: {e['message']}" if e["path"] else e["message"] for e in errors))


# ---------------------------------------------------------------------------------------------
# Paths and values in messages.

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")


def json_path(parts) -> str:
    """('objects', 3, 'radius') -> 'objects[3].radius'; keys that are not names are quoted."""
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        elif _IDENT.match(part):
            out += f".{part}" if out else part
        else:
            out += f"[{json.dumps(part)}]"
    return out


def show_value(value: Any) -> str:
    """A short JSON rendering of a bad input for an error message (NaN shows as NaN)."""
    try:
        text = json.dumps(value, allow_nan=True)
    except (TypeError, ValueError, RecursionError):
        text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# Names other renderers, books and lectures give the scene format's fields (docs/scene-format.md): an unknown
# field among these is suggested the first of its fields that the object has ('colour' -> kd in a material,
# intensity in a point light, color in fog).
SYNONYMS: dict[str, tuple[str, ...]] = {
    **dict.fromkeys(("colour", "color"), ("kd", "color", "radiance", "intensity", "irradiance")),
    **dict.fromkeys(("albedo", "diffuse", "diffuse_color", "diffuse_colour", "base_color", "reflectance"), ("kd",)),
    **dict.fromkeys(("ambient", "ambient_color"), ("ka",)),
    **dict.fromkeys(("specular", "specular_color", "phong"), ("ks",)),
    **dict.fromkeys(("exponent", "phong_exponent", "specular_exponent", "shine", "n", "ns"), ("shininess",)),
    **dict.fromkeys(("reflect", "reflection", "reflective", "reflectivity", "mirror"), ("kr",)),
    **dict.fromkeys(("transparency", "transparent", "transmission", "transmittance", "refraction", "refract"), ("kt",)),
    **dict.fromkeys(("eta", "index", "refractive_index", "index_of_refraction", "ni"), ("ior",)),
    **dict.fromkeys(("emissive", "emit", "emittance", "emission_color"), ("emission", "radiance")),
    **dict.fromkeys(("glossiness", "roughness", "blur"), ("gloss",)),
    **dict.fromkeys(("bump_map", "bumpmap", "normal_map"), ("bump",)),
    **dict.fromkeys(("fov", "fovy", "field_of_view", "angle"), ("vfov",)),
    **dict.fromkeys(("eye", "from", "origin", "camera_position"), ("lookfrom",)),
    **dict.fromkeys(("target", "at", "to", "look_at"), ("lookat",)),
    **dict.fromkeys(("up", "up_vector"), ("vup",)),
    **dict.fromkeys(("aperture", "lens", "aperture_radius"), ("lens_radius",)),
    **dict.fromkeys(("focal_distance", "focus", "focal_length"), ("focus_distance",)),
    **dict.fromkeys(("samples", "samples_per_pixel", "spp_count"), ("spp",)),
    **dict.fromkeys(("depth", "maxdepth", "bounces", "max_bounces", "recursion_depth"), ("max_depth",)),
    **dict.fromkeys(("power", "strength", "brightness"), ("intensity", "radiance", "irradiance", "strength")),
    **dict.fromkeys(("position", "pos", "location"), ("position", "center", "corner", "lookfrom")),
    **dict.fromkeys(("centre",), ("center",)),
    **dict.fromkeys(("dir",), ("direction",)),
    **dict.fromkeys(("xres", "resolution_x"), ("width",)),
    **dict.fromkeys(("yres", "resolution_y"), ("height",)),
}


def did_you_mean(word: Any, choices: list[str]) -> str:
    """ "; did you mean 'x'?" for the closest of `choices` (by spelling, or as a synonym: SYNONYMS), or nothing."""
    key = str(word).strip().lower()
    known = next((c for c in SYNONYMS.get(key, ()) if c in choices), None)
    close = [known] if known else difflib.get_close_matches(str(word), choices, n=1)
    if not close and key != str(word):  # 'Kd', 'IOR'
        close = difflib.get_close_matches(key, choices, n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


# ---------------------------------------------------------------------------------------------
# Following a pydantic location through the model types.


def _unwrap(tp: Any) -> Any:
    """Strip Annotated[...] and Optional[...] from a type."""
    while True:
        if get_origin(tp) is Annotated:
            tp = get_args(tp)[0]
        elif get_origin(tp) in (Union, UnionType) and type(None) in get_args(tp):
            rest = [a for a in get_args(tp) if a is not type(None)]
            if len(rest) != 1:
                return tp
            tp = rest[0]
        else:
            return tp


def _union_tags(tp: Any) -> dict[str, Any]:
    """tag -> member type of a tagged union (by Tag(...) or by the member's `type` literal)."""
    if get_origin(tp) not in (Union, UnionType):
        return {}
    tags = {}
    for member in get_args(tp):
        meta = get_args(member)[1:] if get_origin(member) is Annotated else ()
        tag = next((m.tag for m in meta if isinstance(m, Tag)), None)
        inner = _unwrap(member)
        if tag is None and isinstance(inner, type) and issubclass(inner, BaseModel) and "type" in inner.model_fields:
            tag = get_args(inner.model_fields["type"].annotation)[0]
        if tag is not None:
            tags[tag] = inner
    return tags


def _union_member(tp: Any, label: str) -> Any:
    """The member of a plain union that pydantic names `label` ('str', 'dict[str,any]', a model's name)."""
    for member in get_args(tp):
        inner = _unwrap(member)
        name = getattr(inner, "__name__", str(inner))
        if label == name or label.startswith(f"{name}["):
            return inner
    return None


def _walk(root: Any, loc: tuple) -> tuple[list, Any]:
    """Follow a pydantic loc from `root`: (the JSON path's parts, the type found there)."""
    tp, parts = root, []
    for item in loc:
        tp = _unwrap(tp)
        tags = _union_tags(tp)
        if tags and item in tags:  # a tagged union's tag
            tp = tags[item]
            continue
        if get_origin(tp) in (Union, UnionType) and isinstance(item, str):  # which member of a plain union
            tp = _union_member(tp, item)
            continue
        if isinstance(item, str) and item.startswith("function-"):  # a validator's label
            continue
        parts.append(item)
        origin, args = get_origin(tp), get_args(tp)
        if isinstance(tp, type) and issubclass(tp, BaseModel) and item in tp.model_fields:
            tp = tp.model_fields[item].annotation
        elif origin is dict and args:
            tp = args[1]
        elif origin is list and args:
            tp = args[0]
        elif origin is tuple and args and isinstance(item, int):
            tp = args[min(item, len(args) - 1)]
        else:
            tp = None
    return parts, _unwrap(tp)


# ---------------------------------------------------------------------------------------------
# Messages.


def _num(x: Any) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


_MESSAGES = {
    "float_type": "expected a number, got {input}",
    "int_type": "expected an integer, got {input}",
    "int_parsing": "expected an integer, got {input}",  # a query or path parameter
    "int_from_float": "expected an integer, got {input}",
    "bool_type": "expected true or false, got {input}",
    "string_type": "expected a string, got {input}",
    "finite_number": FINITE,
    "list_type": "expected a list [...], got {input}",
    "tuple_type": "expected a list [...], got {input}",
    "dict_type": "expected a JSON object {{...}}, got {input}",
    "model_type": "expected a JSON object {{...}}, got {input}",
    "model_attributes_type": "expected a JSON object {{...}}, got {input}",
    "greater_than": "must be > {gt}",
    "greater_than_equal": "must be >= {ge}",
    "less_than": "must be < {lt}",
    "less_than_equal": "must be <= {le}",
    "too_short": "must have at least {min_length} item(s)",
    "too_long": "must have at most {max_length} item(s)",
}


def translate_error(err: Mapping[str, Any], root: type[BaseModel] | None = None) -> dict[str, str]:
    """One of pydantic's errors (an item of ValidationError.errors(), its loc relative to `root`) ->
    {"path", "message"} at the offending value's own JSON path. Without `root` the path is the loc as
    it is, less validator labels, and the messages cannot name allowed fields or union members."""
    kind, loc, ctx = err["type"], tuple(err["loc"]), err.get("ctx") or {}
    parts, tp = _walk(root, loc)
    if "message" in ctx:  # our own checks: PydanticCustomError(..., "{message}", {"message": ...})
        message = str(ctx["message"])
    elif kind == "value_error":  # a validator's ValueError
        message = str(ctx.get("error", err["msg"])).removeprefix("Value error, ")
    elif kind == "missing" and isinstance(loc[-1], int):  # a tuple too short
        message = f"missing: the list needs {loc[-1] + 1} items or more"
    elif kind == "missing":
        message = f"required field '{loc[-1]}' is missing"
    elif kind == "extra_forbidden":
        _, owner = _walk(root, loc[:-1])
        fields = list(owner.model_fields) if isinstance(owner, type) and issubclass(owner, BaseModel) else []
        hint = did_you_mean(loc[-1], fields) or (f" (allowed: {', '.join(fields)})" if fields else "")
        message = f"unknown field '{loc[-1]}'{hint}"
    elif kind in ("union_tag_invalid", "union_tag_not_found"):
        tags = list(_union_tags(tp))
        field = next((p for p in reversed(parts) if isinstance(p, str)), "")
        noun = field.removesuffix("s")  # objects -> object, lights -> light, texture
        allowed = f"one of: {', '.join(tags)}"
        if kind == "union_tag_invalid":
            tag = err["input"].get("type") if isinstance(err.get("input"), dict) else ctx.get("tag")
            shown = f"'{tag}'" if isinstance(tag, str) else show_value(tag)
            message = f"unknown {noun} type {shown}; expected {allowed}{did_you_mean(tag, tags)}"
        else:
            message = f"required field 'type' is missing ({allowed})"
        parts = [*parts, "type"]
    elif kind == "literal_error":
        choices = [str(c) for c in get_args(tp)] if get_origin(tp) is Literal else []
        if not choices:  # no model to look the field up in (a route's body): pydantic's own list, "'png' or 'exr'"
            choices = re.findall(r"'([^']*)'", str(ctx.get("expected", "")))
        given = err.get("input")
        message = f"expected one of: {', '.join(choices)}; got {show_value(given)}{did_you_mean(given, choices)}"
    elif kind in ("less_than_equal", "greater_than_equal") and abs(ctx.get("le", ctx.get("ge", 0))) == FLOAT32_MAX:
        message = FLOAT32  # a number's float32 range (the bounds of tracer.scene's F32 and NonNeg)
    elif kind in _MESSAGES:
        values = {k: _num(v) for k, v in ctx.items()}
        message = _MESSAGES[kind].format(input=show_value(err.get("input")), **values)
    else:
        message = err["msg"]
    return {"path": json_path(parts), "message": message}


def pydantic_errors(exc: ValidationError | list[dict], root: type[BaseModel] | None = None) -> list[dict[str, str]]:
    """pydantic's errors (a ValidationError, or its .errors() with locs made relative to `root`) ->
    [{"path", "message"}], each error once, in pydantic's order (see `translate_error`)."""
    out: list[dict[str, str]] = []
    for err in exc.errors() if isinstance(exc, ValidationError) else exc:
        item = translate_error(err, root)
        if item not in out:
            out.append(item)
    return out
