"""Requirements on a submitted scene, checked on the validated scene (defaults filled in).

A triple (a colour, a velocity) compares by its largest component, so {"kt": {"greater_than": 0}}
means "transmits some light"; {"present": true} means set and not zero, empty or null.
"""

from __future__ import annotations

from typing import Any

from tracer.grading.spec import COMPARISONS, Check
from tracer.scene import Mesh, Scene, primitive_count


def _scalar(v: Any) -> Any:
    if isinstance(v, list | tuple) and v and all(isinstance(x, int | float) for x in v):
        return max(v)
    return v


def _present(v: Any) -> bool:
    if v is None or v is False:
        return False
    if isinstance(v, int | float):
        return v != 0
    if isinstance(v, list | tuple):
        return any(_present(x) for x in v)
    if isinstance(v, dict | str):
        return len(v) > 0
    return True


def _compare(v: Any, word: str, target: Any) -> bool:
    if word == "present":
        return _present(v) == bool(target)
    if v is None:
        return False
    v = _scalar(v)
    try:
        return bool(COMPARISONS[word][1](v, target))
    except TypeError:  # e.g. a string against a number
        return False


def _matches(item: dict, where: dict) -> bool:
    for key, test in where.items():
        tests = test if isinstance(test, dict) else {"equals": test}
        if not all(_compare(item.get(key), word, target) for word, target in tests.items()):
            return False
    return True


def _items(scene: Scene, what: str) -> list[dict]:
    if what == "materials":  # the materials the objects use, each once
        used, seen = [], set()
        for obj in scene.objects:
            key = obj.material if isinstance(obj.material, str) else id(obj.material)
            if key not in seen:
                seen.add(key)
                used.append(scene.material_for(obj).model_dump())
        return used
    if what == "lights":
        return [light.model_dump() for light in scene.lights]
    return [obj.model_dump() for obj in scene.objects]


def _value(scene: Scene, path: str) -> tuple[bool, Any]:
    v: Any = scene.model_dump()
    for part in path.split("."):
        if isinstance(v, dict) and part in v:
            v = v[part]
        elif isinstance(v, list) and part.isdigit() and int(part) < len(v):
            v = v[int(part)]
        else:
            return False, None
    return True, v


def primitives(scene: Scene, mesh_triangles: dict[int, int] | None = None) -> int:
    """Shapes plus triangles (a box is 12; a mesh file its faces, given by the caller who read it)."""
    n = primitive_count(scene.objects)
    for i, obj in enumerate(scene.objects):
        if isinstance(obj, Mesh) and obj.file and mesh_triangles:
            n += mesh_triangles.get(i, 0)
    return n


def _show(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_show(x) for x in v) + "]"
    return str(v)


def _words(check: Check) -> str:
    return " and ".join(f"{COMPARISONS[w][0]} {_show(t)}" for w, t in check.comparisons().items())


def run_check(scene: Scene, check: Check, mesh_triangles: dict[int, int] | None = None) -> tuple[bool, str]:
    """(passed, what was found), e.g. (False, "found 0 materials with kt > 0, ior > 1; wanted >= 1")."""
    if check.value is not None:
        found, v = _value(scene, check.value)
        if not found:
            return False, f"{check.value}: no such field in the scene"
        ok = all(_compare(v, w, t) for w, t in check.comparisons().items())
        return ok, f"{check.value} is {_show(v)}; wanted {_words(check)}"
    if check.count == "primitives":
        n = primitives(scene, mesh_triangles)
        what = "primitives"
    else:
        assert check.count is not None, "a check counts or reads a value (the spec's validator)"
        n = sum(_matches(item, check.where) for item in _items(scene, check.count))
        what = check.count
    if check.where:
        conds = []
        for key, test in check.where.items():
            tests = test if isinstance(test, dict) else {"equals": test}
            for w, t in tests.items():
                word = ("set" if t else "unset") if w == "present" else f"{COMPARISONS[w][0]} {_show(t)}"
                conds.append(f"{key} {word}")
        what += " with " + ", ".join(conds)
    ok = all(_compare(n, w, t) for w, t in check.comparisons().items())
    return ok, f"found {n} {what}; wanted {_words(check)}"
