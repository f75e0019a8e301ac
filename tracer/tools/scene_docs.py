"""The field tables of docs/scene-format.md, generated from the scene models.

The reference is written by hand, except its field tables: each sits between two markers,

    <!-- fields: Camera -->
    ...
    <!-- end fields -->

and is made from the pydantic model of that name in tracer/scene/: every field in order, its
type and limits (from the published JSON Schema), its default, and its description (meaning and
unit). `Object` stands for the fields every object has; an object type's own table lists only its
own fields. `python -m tracer docs` rewrites the tables in place; `--check` says whether the file
is up to date (the tests run it), so the reference cannot drift from the models.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from pydantic import BaseModel

from tracer import scene as S
from tracer.errors import FLOAT32_MAX

DOC = Path(__file__).resolve().parents[2] / "docs" / "scene-format.md"
BLOCK = re.compile(r"(<!-- fields: (\w+) -->\n)(.*?)(<!-- end fields -->)", re.S)
HEADING = re.compile(r"^(#{1,6}) (.+)$", re.M)
OBJECT = "Object"  # the fields every object has (tracer.scene._Object)


def models() -> dict[str, type[BaseModel]]:
    """Every model of the format by name: the scene and all it references, plus `Object`."""
    out = {name: getattr(S, name) for name in S.scene_json_schema()["$defs"]}
    out["Scene"] = S.Scene
    out[OBJECT] = S._Object
    return out


def slug(heading: str) -> str:
    """A heading's anchor, as GitHub and the service's page make it: `Camera rays` -> `camera-rays`."""
    text = re.sub(r"<[^>]+>", "", heading).strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(text: str) -> dict[str, str]:
    """Model name -> the anchor of the heading its table sits under."""
    out = {}
    for block in BLOCK.finditer(text):
        headings = HEADING.findall(text[: block.start()])
        if headings:
            out[block[2]] = slug(headings[-1][1])
    return out


def _value(v) -> str:
    """A default as compact JSON: 40 rather than 40.0, [0, 1, 0] rather than (0.0, 1.0, 0.0)."""
    if isinstance(v, bool) or v is None:
        return json.dumps(v)
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)}: {_value(x)}" for k, x in v.items()) + "}"
    return json.dumps(v)


def _default(field) -> str:
    if field.is_required():
        return "required"
    if field.default_factory is not None:
        made = field.default_factory()
        return "its defaults" if isinstance(made, BaseModel) else f"`{_value(made)}`"
    return f"`{_value(field.default)}`"


def _bounds(p: dict, integer: bool) -> str:
    lo, lo_open = (p["exclusiveMinimum"], True) if "exclusiveMinimum" in p else (p.get("minimum"), False)
    hi, hi_open = (p["exclusiveMaximum"], True) if "exclusiveMaximum" in p else (p.get("maximum"), False)
    if lo is not None and lo <= -FLOAT32_MAX:  # float32's range holds for every number: said once, in the prose
        lo = None
    if hi is not None and hi >= FLOAT32_MAX:
        hi = None
    if integer:  # integers: closed ranges read best
        lo, lo_open = (lo + 1, False) if lo is not None and lo_open else (lo, lo_open)
        hi, hi_open = (hi - 1, False) if hi is not None and hi_open else (hi, hi_open)
    if lo is not None and hi is not None and not lo_open and not hi_open:
        return f" from {_value(lo)} to {_value(hi)}"
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '≥'} {_value(lo)}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '≤'} {_value(hi)}")
    return (" " + " and ".join(parts)) if parts else ""


class _Types:
    """JSON Schema fragments -> short readable types, with links to the sections of the models."""

    def __init__(self, defs: dict, anchors: dict[str, str]):
        self.defs, self.anchors = defs, anchors

    def link(self, ref: str) -> str:
        name = ref.rsplit("/", 1)[-1]
        kind = self.defs.get(name, {}).get("properties", {}).get("type", {}).get("const")
        text = f"`{kind}`" if kind else name
        return f"[{text}](#{self.anchors[name]})" if name in self.anchors else text

    def __call__(self, p: dict) -> str:
        if "$ref" in p:
            return self.link(p["$ref"])
        for key in ("anyOf", "oneOf"):
            if key in p:
                return self.union(p[key])
        if "const" in p:
            return f"`{json.dumps(p['const'])}`"
        if "enum" in p:
            return "one of " + ", ".join(f"`{json.dumps(e)}`" for e in p["enum"])
        kind = p.get("type")
        if kind in ("number", "integer"):
            return kind + _bounds(p, kind == "integer")
        if kind == "boolean":
            return "`true` or `false`"
        if kind in ("string", "null"):
            return kind
        if kind == "array":
            return self.array(p)
        if kind == "object":
            extra = p.get("additionalProperties")
            return f"object: name → {self(extra)}" if isinstance(extra, dict) else "object"
        return "any"

    def union(self, members: list[dict]) -> str:
        nullable = any(m.get("type") == "null" for m in members)
        rest = [m for m in members if m.get("type") != "null"]
        numbers = [m for m in rest if m.get("type") == "number"]
        triples = [m for m in rest if m.get("type") == "array" and len(m.get("prefixItems", ())) == 3]
        if len(rest) == 2 and numbers and triples:  # one number stands for three equal ones
            if numbers[0].get("minimum") == 0:
                text = "RGB `[r, g, b]` ≥ 0, or one number for all three"
            else:
                text = "number, or `[x, y, z]`"
        else:
            text = " or ".join(self(m) for m in rest)
        return text + (", or `null`" if nullable else "")

    def array(self, p: dict) -> str:
        items = p.get("prefixItems")
        if items:
            if all(i.get("type") == "array" for i in items):
                return f"{len(items)} points `[x, y, z]`"
            integers = {i.get("type") for i in items} == {"integer"}
            names = {2: "[a, b]", 3: "[i, j, k]" if integers else "[x, y, z]"}.get(len(items), f"{len(items)} values")
            text = f"`{names}`" + (" of integers" if integers else "")
            bound = _bounds(items[0], False)
            return text + (f", each{bound}" if bound else "")
        inner = p.get("items", {})
        prefix = "non-empty list" if p.get("minItems", 0) >= 1 else "list"
        return f"{prefix} of {self(inner)}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def table(name: str, anchors: dict[str, str]) -> str:
    """The field table of model `name` (see the module's docstring)."""
    schema = S.scene_json_schema()
    defs = schema["$defs"]
    types = _Types(defs, anchors)
    model = models()[name]
    if name == OBJECT:
        props = defs["Sphere"]["properties"]
        fields = list(S._Object.model_fields)
    elif issubclass(model, S._Object):
        props = defs[name]["properties"]
        own = set(model.__annotations__)  # declared here, not inherited
        fields = [f for f in model.model_fields if f in own]
    else:
        props = schema["properties"] if name == "Scene" else defs[name]["properties"]
        fields = list(model.model_fields)
    rows = ["| field | type | default | meaning (unit) |", "| --- | --- | --- | --- |"]
    for field in fields:
        info = model.model_fields[field]
        kind = "one of the object types below" if name == OBJECT and field == "type" else types(props[field])
        rows.append(f"| `{field}` | {_cell(kind)} | {_cell(_default(info))} | {_cell(info.description or '')} |")
    return "\n".join(rows) + "\n"


def render(text: str) -> str:
    """The document with every field table made again from the models."""
    anchors = _anchors(text)
    known = models()
    for block in BLOCK.finditer(text):
        if block[2] not in known:
            raise KeyError(f"docs: no model named {block[2]!r} (one of: {', '.join(sorted(known))})")
    # blank lines around the table: a line right after a table would be read as one more row
    return BLOCK.sub(lambda m: m[1] + "\n" + table(m[2], anchors) + "\n" + m[4], text)


def missing(text: str) -> list[str]:
    """Models of the format that have no table in the document."""
    documented = {m[2] for m in BLOCK.finditer(text)}
    return sorted(set(models()) - documented)


def main(check: bool = False, path: Path = DOC) -> int:
    """Rewrite the tables of `path` (or, with `check`, say whether they are up to date): exit status."""
    text = path.read_text(encoding="utf-8")
    fresh = render(text)
    gaps = missing(text)
    if gaps:
        print(f"{path}: no field table for {', '.join(gaps)} (add <!-- fields: NAME --> blocks)")
        return 1
    if check:
        if fresh != text:
            print(f"{path}: the field tables differ from tracer/scene/; run python -m tracer docs")
            return 1
        print(f"{path}: up to date")
        return 0
    if fresh != text:
        path.write_text(fresh, encoding="utf-8")
        print(f"{path}: field tables written")
    else:
        print(f"{path}: already up to date")
    return 0
