"""A scene as a canonical set of facts, for similarity reports (tracer/grading/similarity.py).

A scene file says the same scene in many ways: objects in any order, materials under any names, a number
written 0.5 or 0.501, a default written out or left off. Its *canonical* form forgets all of that: it is a set
of `path=value` facts, one per field of the camera, the film and the render settings, and per field of each
object and light, where

- an object's facts are keyed by its **kind and where it is** (`sphere@(0,1,-2).radius=0.5`), never by its
  name or its index, so reordering the objects changes nothing;
- its material is written **into** the object by its values (`sphere@(0,1,-2).material.kt=1`), never by its
  name, so renaming the materials changes nothing; names (of objects, materials, the scene) are no facts;
- a field equal to its default (the scene models' own, tracer/scene/) is no fact, written out or not, and an
  RGB triple of three equal numbers is that number (as the format reads it);
- every number is **rounded to a grid**: steps of 0.05 below 1 in magnitude, steps of 5 % above (a
  logarithmic grid, which meets the linear one near 1), whose lines are off the round numbers people write
  (0.0137 + 0.05 k). A nudge of +0.001 would still cross a grid line now and then, so each fact is written on
  two grids, the second shifted by half a step (`~` before its path): a nudge smaller than a quarter step
  crosses a line of at most one of the two, and the number on the other still matches.

`facts` holds both grids' facts (what MinHash and the distance read); `shown` maps each fact of the first grid
to its path and the value as the scene wrote it (what a person reads beside the other student's). A starter
scene's facts are taken away before students are compared (`own`), so what every student was given is no
evidence. Pure: plain data in, plain data out, no file read."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

from pydantic_core import PydanticUndefined

from tracer.scene.camera import Camera, Film, Sampler
from tracer.scene.lights import DirectionalLight, DiskLight, PointLight, QuadLight, SphereLight, SpotLight
from tracer.scene.materials import Material
from tracer.scene.objects import Box, Disk, Mesh, Plane, Quad, Sphere, Transform, Triangle
from tracer.scene.render import Fog, RenderSettings

LINEAR_STEP = 0.05  # the grid below 1 in magnitude (coefficients, colours, small positions)
LOG_STEP = math.log(1.05)  # above 1: steps of 5 % (a camera at 3.9 or 4.0 is not the same choice; 200 or 201 is)
OFFSET = 0.0137  # the first grid's lines are at 0.0137 + 0.05 k: never on a number written with two decimals
SWITCH = 1 + OFFSET  # where the 5 % steps start: a line of the linear grid
ANCHOR_SCALE = 4  # where a thing is, on a grid 4 times coarser: a nudge that crosses a line there would change
# every fact of the thing at once
MAX_LIST = 12  # numbers of a list shown in full; a longer one (a mesh's vertices) is summarised
MAX_TEXT = 60  # characters of a string value kept

OBJECTS = {"sphere": Sphere, "plane": Plane, "quad": Quad, "disk": Disk, "box": Box, "triangle": Triangle,
           "mesh": Mesh}  # fmt: skip
LIGHTS = {"point": PointLight, "directional": DirectionalLight, "spot": SpotLight, "quad": QuadLight,
          "disk": DiskLight, "sphere": SphereLight}  # fmt: skip
ANCHORS = ("center", "corner", "point", "position", "min", "vertices", "direction")  # where a thing is
NOT_FACTS = {"type", "name", "material"}  # the kind is in the key; names say nothing; the material is inlined
SETTINGS = {"camera": Camera, "film": Film, "sampler": Sampler, "render": RenderSettings, "fog": Fog}  # by field


def _defaults(model) -> dict[str, Any]:
    return {n: f.default for n, f in model.model_fields.items() if f.default is not PydanticUndefined}


MATERIAL_DEFAULTS = _defaults(Material)
TRANSFORM_DEFAULTS = _defaults(Transform)


def grid(x: float, shifted: bool = False, scale: int = 1) -> str:
    """A number's cell on the first grid (or the second, `shifted` half a step), as the text of the cell's middle.
    Cells are LINEAR_STEP wide below SWITCH in magnitude and 5 % wide above. No line of either grid lies on a
    number people write (0.7, 1.25, 2): the lines sit OFFSET off the round numbers. `scale`: cells that many
    times wider (where a thing is: ANCHOR_SCALE)."""
    if not math.isfinite(x):
        return str(x)
    step, log_step = LINEAR_STEP * scale, LOG_STEP * scale
    off = OFFSET + (step / 2 if shifted else 0.0)
    switch = SWITCH * (math.exp(log_step / 2) if shifted else 1.0)  # each grid's own line
    if abs(x) < switch:
        k = math.floor((x - off) / step)
        middle = off + (k + 0.5) * step
    else:
        k = math.floor(math.log(abs(x) / switch) / log_step)
        middle = math.copysign(switch * math.exp((k + 0.5) * log_step), x)
    return f"{middle:.3g}"


def _same(value: Any, default: Any) -> bool:
    return _norm(value) == _norm(default)


def _norm(v: Any) -> Any:
    """A value as the format reads it: a triple of equal numbers is that number; tuples are lists."""
    if isinstance(v, list | tuple):
        items = [_norm(x) for x in v]
        if len(items) == 3 and all(isinstance(x, int | float) and not isinstance(x, bool) for x in items):
            if items[0] == items[1] == items[2]:
                return float(items[0])
        return items
    if isinstance(v, int | float) and not isinstance(v, bool):
        return float(v)
    if isinstance(v, dict):
        return {k: _norm(x) for k, x in v.items()}
    return v


def value_text(v: Any, shifted: bool | None = None, scale: int = 1) -> str:
    """A value as a fact writes it: numbers on the grid (`shifted`: the second; None: as written, for people)."""
    v = _norm(v)
    if isinstance(v, bool) or v is None:
        return json.dumps(v)
    if isinstance(v, float):
        return f"{v:.6g}" if shifted is None else grid(v, shifted, scale)
    if isinstance(v, str):
        return json.dumps(v[:MAX_TEXT])
    if isinstance(v, list):
        flat = _numbers(v)
        if len(flat) > MAX_LIST:  # a mesh's vertices: how many, and the box around them
            if not flat:
                return f"[{len(v)} items]"
            lo, hi = min(flat), max(flat)
            return f"[{len(v)} items in {value_text(lo, shifted, scale)}..{value_text(hi, shifted, scale)}]"
        return "(" + ",".join(value_text(x, shifted, scale) for x in v) + ")"
    if isinstance(v, dict):
        return "{" + ",".join(f"{k}:{value_text(x, shifted, scale)}" for k, x in sorted(v.items())) + "}"
    return json.dumps(str(v)[:MAX_TEXT])


def _numbers(v: Any) -> list[float]:
    if isinstance(v, int | float) and not isinstance(v, bool):
        return [float(v)]
    if isinstance(v, list | tuple):
        return [x for item in v for x in _numbers(item)]
    return []


def _anchor(thing: dict) -> Any:
    """Where an object or light is: its first point field (a triangle's or mesh's vertices: their centroid; a
    mesh from a file: the file and its translation)."""
    for name in ANCHORS:
        v = thing.get(name)
        if v is None:
            continue
        if name == "vertices":
            pts = [p for p in v if isinstance(p, list | tuple) and len(p) == 3] if isinstance(v, list) else []
            nums = [_numbers(p) for p in pts]
            if nums and all(len(p) == 3 for p in nums):
                return [sum(p[i] for p in nums) / len(nums) for i in range(3)]
            continue
        return v
    if thing.get("file") is not None:
        t = thing.get("transform")
        t = t if isinstance(t, dict) else {}
        return [str(thing["file"])[:MAX_TEXT], t.get("translate", [0, 0, 0])]
    return None


@dataclass
class Canonical:
    """A scene's facts: `facts` on both grids; `shown`: each first-grid fact -> (its path, the path as a person
    reads it: where a thing is as written, not its cell; the value as written)."""

    facts: set[str] = field(default_factory=set)
    shown: dict[str, tuple[str, str, str]] = field(default_factory=dict)

    def add(self, path: str, value: Any, shifted_path: str | None = None, read_as: str | None = None) -> None:
        fact = f"{path}={value_text(value, False)}"
        self.facts.add(fact)
        self.facts.add(f"~{shifted_path or path}={value_text(value, True)}")
        self.shown[fact] = (path, read_as or path, value_text(value))

    def own(self, given: Canonical | None) -> Canonical:
        """The facts that are not `given`'s (a starter scene's): what the student made."""
        if given is None:
            return self
        return Canonical(self.facts - given.facts, {f: s for f, s in self.shown.items() if f not in given.facts})


def _flatten(prefix: str, value: Any, defaults: dict[str, Any], out: list[tuple[str, Any]]) -> None:
    """(path, value) of each field of a section that is not its default; nested sections (a texture, a
    transform) as `a.b`."""
    if not isinstance(value, dict):
        return
    for name, v in sorted(value.items()):
        if name in NOT_FACTS and prefix.count(".") < 2 or (name in defaults and _same(v, defaults[name])):
            continue
        if isinstance(v, dict):
            inner = TRANSFORM_DEFAULTS if name == "transform" else {}
            _flatten(f"{prefix}.{name}", v, inner, out)
        else:
            out.append((f"{prefix}.{name}", v))


def _thing(c: Canonical, kind: str, thing: dict, model, material: dict | None) -> None:
    anchor = _anchor(thing)
    where = value_text(anchor, False, ANCHOR_SCALE), value_text(anchor, True, ANCHOR_SCALE)
    key, shifted_key = f"{kind}@{where[0]}", f"{kind}@{where[1]}"
    fields: list[tuple[str, Any]] = []
    _flatten("", thing, _defaults(model) if model is not None else {}, fields)
    if material is not None:
        _flatten(".material", material, MATERIAL_DEFAULTS, fields)
    if not fields:  # a thing with nothing but its place is still a fact
        fields = [(".at", anchor)]
    written = f"{kind}@{value_text(anchor)}"
    for path, v in fields:
        c.add(key + path, v, shifted_key + path, written + path)


def _list(v: Any) -> list:
    return v if isinstance(v, list) else []


def _kind(thing: dict) -> str:
    return str(thing.get("type"))[:20]


def canonical(scene: Any) -> Canonical | None:
    """A scene (a dict, as its JSON reads) as its facts; None for what is no scene at all (not an object).
    A scene the validator would refuse is still read as far as it goes: similarity is about what was written."""
    if not isinstance(scene, dict):
        return None
    c = Canonical()
    materials = scene.get("materials")
    materials = materials if isinstance(materials, dict) else {}
    for name, model in SETTINGS.items():
        fields: list[tuple[str, Any]] = []
        _flatten(name, scene.get(name), _defaults(model), fields)
        for path, v in fields:
            c.add(path, v)
    for name in ("background", "ambient"):
        if name in scene and not _same(scene[name], 0.0):
            c.add(name, scene[name])
    for obj in _list(scene.get("objects")):
        if isinstance(obj, dict):
            m = obj.get("material")
            material = materials.get(m) if isinstance(m, str) else m
            material = material if isinstance(material, dict) else {}
            kind = _kind(obj)
            _thing(c, kind, obj, OBJECTS.get(kind), material)
    for light in _list(scene.get("lights")):
        if isinstance(light, dict):
            _thing(c, f"light.{_kind(light)}", light, LIGHTS.get(_kind(light)), None)
    return c


def read(text: bytes | str) -> Canonical | None:
    """A scene file's text as its facts; None when it is not a JSON object."""
    try:
        return canonical(json.loads(text))
    except (ValueError, RecursionError):
        return None
