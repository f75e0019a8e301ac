"""A tree log for your own ray tracer: the rays of a few pixels, as the service's feedback reads them.

Copy this file next to your tracer (Python 3, no dependencies). For each pixel the feedback names, trace the ray
through the pixel's centre and tell the log about every ray you trace: the eye ray, each shadow ray, each
reflection and transmission ray, with its parent. Then write the log and upload it.

    from treelog import TreeLog

    log = TreeLog()
    tree = log.pixel(12, 30)                                  # x from the left, y from the top
    eye = tree.eye(origin, direction)                         # returns the node's id
    tree.hit(eye, t, point, normal, obj)                      # or tree.miss(eye); normal: the shading normal
    tree.shadow(eye, origin, direction, light=0, occluded=False, radiance=contribution, weight=w)
    r = tree.reflection(eye, origin, direction, weight=w_r)   # trace it, then tree.hit(r, ...) or tree.miss(r)
    tree.set(eye, radiance=L, weight=[1, 1, 1], terms={"ambient": a, "diffuse": d, "specular": s})
    tree.color = L                                            # optional: the pixel's final linear colour
    log.write("treelog.json")

Vectors are any three numbers (a list, a tuple, a numpy array, an object with x, y, z). A number that is not
finite (NaN, infinity) is written as null, so the file stays JSON and the service's check names the field.
The format: docs/scene-format.md, "Tree log"; at most 64 trees and 4 MB a log.
"""

from __future__ import annotations

import json
import math

KINDS = ("eye", "shadow", "reflection", "transmission")


def _number(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _vec(v) -> list | None:
    """Three numbers from a sequence or an object with x, y, z; None stays None."""
    if v is None:
        return None
    if hasattr(v, "x") and not hasattr(v, "__len__"):
        v = (v.x, v.y, v.z)
    if isinstance(v, (int, float)):
        v = (v, v, v)
    values = [_number(c) for c in v]
    if len(values) != 3:
        raise ValueError(f"a vector has three numbers, not {len(values)}")
    return values


class PixelTree:
    """The rays traced for one pixel: a flat list of nodes, each with its parent's id."""

    def __init__(self, x: int, y: int):
        self.x, self.y = int(x), int(y)
        self.color = None  # the pixel's final linear colour (optional)
        self.nodes: list[dict] = []

    def add(self, kind: str, parent: int | None, origin, direction, weight=None) -> int:
        """A ray of `kind` (eye, shadow, reflection, transmission) from `origin` along `direction`, child of
        node `parent` (None for the eye ray); returns its id. Its hit and what it carries come later (`hit`,
        `miss`, `set`)."""
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(KINDS)}, not {kind!r}")
        if (parent is None) != (kind == "eye"):
            raise ValueError("the eye ray has no parent; every other ray has one")
        if parent is not None and not 0 <= parent < len(self.nodes):
            raise ValueError(f"no node {parent} to be the parent")
        node = {"id": len(self.nodes), "parent": parent, "kind": kind, "origin": _vec(origin)}
        node.update(direction=_vec(direction), t=None, hit=None, weight=_vec(weight))
        self.nodes.append(node)
        return node["id"]

    def eye(self, origin, direction) -> int:
        """The eye ray through the pixel's centre (its weight is 1)."""
        return self.add("eye", None, origin, direction, weight=(1.0, 1.0, 1.0))

    def reflection(self, parent: int, origin, direction, weight=None) -> int:
        """A reflection ray; `weight` the product of the K's (kr, Fresnel) from the eye down to it."""
        return self.add("reflection", parent, origin, direction, weight)

    def transmission(self, parent: int, origin, direction, weight=None) -> int:
        """A transmission (refracted) ray; `weight` the product of the K's from the eye down to it."""
        return self.add("transmission", parent, origin, direction, weight)

    def shadow(
        self, parent: int, origin, direction, light: int, occluded: bool, t=None, hit=None, radiance=None, weight=None
    ) -> int:
        """A shadow ray from the parent's hit towards light number `light`: blocked (`occluded`, with the
        occluder's distance `t` and `hit` = (point, normal, object)) or not; `radiance` the light's
        contribution f_att I cos(theta) f (0 when blocked), `weight` the parent's weight."""
        node = self.add("shadow", parent, origin, direction, weight)
        self.set(node, light=int(light), occluded=bool(occluded), radiance=radiance)
        if occluded and hit is not None:
            self.hit(node, t, *hit)
        elif occluded and t is not None:
            self.set(node, t=t)
        return node

    def hit(self, node: int, t: float, point, normal, obj: int) -> None:
        """Node `node` hit object number `obj` (its index in the scene's objects) at distance t, at `point`,
        with the shading normal `normal` (turned towards the ray)."""
        n = self.nodes[node]
        n["t"] = _number(t)
        n["hit"] = {"point": _vec(point), "normal": _vec(normal), "object": int(obj)}

    def miss(self, node: int) -> None:
        """Node `node` left the scene (t and hit null)."""
        self.nodes[node]["t"] = None
        self.nodes[node]["hit"] = None

    def set(self, node: int, **fields) -> None:
        """Set fields of a node: radiance, weight (vectors), terms ({ambient, diffuse, specular}), light,
        occluded, t."""
        n = self.nodes[node]
        for key, value in fields.items():
            if key in ("radiance", "weight", "origin", "direction"):
                n[key] = _vec(value)
            elif key == "terms":
                n[key] = None if value is None else {k: _vec(v) for k, v in value.items()}
            elif key == "t":
                n[key] = None if value is None else _number(value)
            elif key in ("light", "occluded"):
                n[key] = value
            else:
                raise ValueError(f"a node has no field {key!r}")

    def as_dict(self) -> dict:
        tree = {"pixel": [self.x, self.y], "nodes": self.nodes}
        if self.color is not None:
            tree["color"] = _vec(self.color)
        return tree


class TreeLog:
    """The trees of a few pixels; `write` saves the JSON the service takes."""

    MAX_TREES = 64

    def __init__(self):
        self.trees: list[PixelTree] = []

    def pixel(self, x: int, y: int) -> PixelTree:
        """A new tree for pixel (x, y), x from the left, y from the top."""
        if len(self.trees) >= self.MAX_TREES:
            raise ValueError(f"a tree log holds at most {self.MAX_TREES} trees")
        tree = PixelTree(x, y)
        self.trees.append(tree)
        return tree

    def as_dict(self) -> dict:
        return {"trees": [t.as_dict() for t in self.trees]}

    def dumps(self) -> str:
        return json.dumps(self.as_dict(), allow_nan=False)

    def write(self, path) -> None:
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.dumps())
