"""A tree log: what a student's own ray tracer writes for a few pixels (docs/own-tracer.md, and "Tree log" in
docs/scene-format.md), read and checked here before anything compares it.

    {"trees": [{"pixel": [x, y], "color": [r, g, b], "nodes": [
        {"id": 0, "parent": null, "kind": "eye", "origin": [..], "direction": [..], "t": 4.2,
         "hit": {"point": [..], "normal": [..], "object": 3}, "radiance": [..], "weight": [..],
         "terms": {"ambient": [..], "diffuse": [..], "specular": [..]}}, ...]}]}

Each node names its `parent` (null for the eye ray, the one root); `kind` is eye | shadow | reflection |
transmission; `t` is null for a miss (for a shadow ray: null when it reached the light). Every other field is
optional, and fields not listed are ignored, so a tracer may log more. Every error is reported at once, at its
JSON path (`trees[2].nodes[5].direction`), like a scene's.
"""

from __future__ import annotations

import json
import math
from typing import Annotated, Any, Literal

from annotated_types import Ge
from pydantic import AllowInfNan, BaseModel, ConfigDict, Field, Strict, ValidationError

from tracer.errors import SceneError, pydantic_errors

MAX_TREES = 64  # trees in one log
MAX_BYTES = 4 * 1024 * 1024  # a log's JSON text
MAX_NODES = 4096  # nodes in one tree (the reference's trees are bounded by max_depth and the lights)

Float = Annotated[float, Strict(), AllowInfNan(False)]
Count = Annotated[int, Strict(), Ge(0)]
Triple = tuple[Float, Float, Float]
KINDS = ("eye", "shadow", "reflection", "transmission")


class _Model(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)  # a tracer may log more than is compared


class LoggedHit(_Model):
    point: Triple | None = None  # where the ray hit, world space
    normal: Triple | None = None  # the shading normal there (turned to face the ray)
    object: Count | None = None  # index in the scene's `objects`
    object_name: str | None = None  # or the object's `name`


class LoggedTerms(_Model):
    ambient: Triple | None = None  # ka * Ia
    diffuse: Triple | None = None  # the diffuse part of the lights' sum
    specular: Triple | None = None  # the specular part of the lights' sum


class LoggedNode(_Model):
    id: Annotated[int, Strict()]
    parent: Annotated[int, Strict()] | None
    kind: Literal["eye", "shadow", "reflection", "transmission"]
    origin: Triple
    direction: Triple  # need not be unit: compared normalised
    t: Annotated[float, Strict(), AllowInfNan(False), Ge(0)] | None  # null: a miss; shadow: null = reached
    hit: LoggedHit | None = None
    light: Count | None = None  # shadow rays: the light's index in `lights`
    occluded: Annotated[bool, Strict()] | None = None
    radiance: Triple | None = None  # what the ray carries back, linear, before its own weight
    weight: Triple | None = None  # the product of K's from the eye down to this ray
    terms: LoggedTerms | None = None  # the local Phong terms at the hit


class LoggedTree(_Model):
    pixel: tuple[Count, Count]  # [x, y] from the top left
    color: Triple | None = None  # the pixel's final linear colour
    nodes: list[LoggedNode] = Field(min_length=1, max_length=MAX_NODES)


class TreeLog(_Model):
    trees: list[LoggedTree] = Field(min_length=1, max_length=MAX_TREES)


def _structure(trees: list[tuple[int, LoggedTree]], width: int | None, height: int | None) -> list[dict]:
    """The errors pydantic cannot see: pixels in the image and once each, ids once each, one eye ray at the
    root, every parent a ray of the same tree, no cycle, nothing below a shadow ray."""
    errors: list[dict] = []
    seen: dict[tuple[int, int], int] = {}
    for i, tree in trees:
        at = f"trees[{i}]"
        x, y = tree.pixel
        if width is not None and height is not None and not (x < width and y < height):
            errors.append({"path": f"{at}.pixel", "message": f"must be a pixel of the {width}x{height} image, "
                           f"x in 0..{width - 1}, y in 0..{height - 1} from the top left; got [{x}, {y}]"})  # fmt: skip
        if (x, y) in seen:
            errors.append({"path": f"{at}.pixel", "message": f"pixel [{x}, {y}] is logged twice (trees[{seen[x, y]}])"})
        seen.setdefault((x, y), i)
        index: dict[int, int] = {}
        for j, n in enumerate(tree.nodes):
            if n.id in index:
                errors.append({"path": f"{at}.nodes[{j}].id", "message": f"id {n.id} is used twice in this tree "
                               f"(nodes[{index[n.id]}])"})  # fmt: skip
            index.setdefault(n.id, j)
        roots = [j for j, n in enumerate(tree.nodes) if n.parent is None]
        if len(roots) != 1:
            where = ", ".join(f"nodes[{j}]" for j in roots) or "none"
            errors.append({"path": f"{at}.nodes", "message": f"must have exactly one root (parent null), the eye "
                           f"ray; found {len(roots)}: {where}"})  # fmt: skip
        for j, n in enumerate(tree.nodes):
            path = f"{at}.nodes[{j}]"
            if n.parent is None and n.kind != "eye":
                errors.append({"path": f"{path}.kind", "message": f"the root (parent null) must be the eye ray, "
                               f"got '{n.kind}'"})  # fmt: skip
            if n.parent is not None and n.kind == "eye":
                errors.append({"path": f"{path}.kind", "message": "an eye ray has no parent (parent must be null)"})
            if n.parent is not None and n.parent not in index:
                errors.append({"path": f"{path}.parent", "message": f"no node with id {n.parent} in this tree"})
            elif n.parent is not None and tree.nodes[index[n.parent]].kind == "shadow":
                errors.append({"path": f"{path}.parent", "message": f"node {n.parent} is a shadow ray: nothing "
                               "is traced from a shadow ray"})  # fmt: skip
            if not any(n.direction):
                errors.append({"path": f"{path}.direction", "message": "must not be a zero-length vector"})
            if n.kind == "shadow" and n.light is None and n.t is None and n.occluded:
                errors.append({"path": f"{path}.t", "message": "an occluded shadow ray needs the occluder's "
                               "distance t"})  # fmt: skip
        # every node reaches the root by its parents (no cycle)
        if len(roots) == 1 and all(n.parent is None or n.parent in index for n in tree.nodes):
            ok: set[int] = {tree.nodes[roots[0]].id}
            for j, n in enumerate(tree.nodes):
                chain, cur = [], n
                while cur.id not in ok and len(chain) <= len(tree.nodes):
                    chain.append(cur.id)
                    if cur.parent is None:
                        break
                    cur = tree.nodes[index[cur.parent]]
                if cur.id in ok:
                    ok.update(chain)
                else:
                    errors.append({"path": f"{at}.nodes[{j}].parent", "message": "the parents from this node "
                                   "go round in a cycle and never reach the eye ray"})  # fmt: skip
                    ok.update(chain)  # one error per cycle
    return errors


def parse(data: bytes | str | dict | Any, width: int | None = None, height: int | None = None) -> TreeLog:
    """A tree log from its JSON text or its parsed value, checked (for an image of width x height pixels when
    given); SceneError with every error at its path otherwise."""
    if isinstance(data, bytes | str):
        size = len(data.encode() if isinstance(data, str) else data)
        if size > MAX_BYTES:
            raise SceneError([{"path": "", "message": f"the tree log is {size} bytes; at most {MAX_BYTES} "
                               f"(4 MB) are taken: log fewer or smaller trees"}])  # fmt: skip
        try:
            data = json.loads(data, parse_constant=lambda c: math.nan)
        except (ValueError, RecursionError) as e:
            raise SceneError([{"path": "", "message": f"not valid JSON: {e}"}]) from None
    if not isinstance(data, dict):
        raise SceneError([{"path": "", "message": 'expected a JSON object {"trees": [...]}'}])
    if not isinstance(data.get("trees"), list):
        raise SceneError([{"path": "trees", "message": 'expected a list of trees: {"trees": [{"pixel": [x, y], '
                           '"nodes": [...]}, ...]}'}])  # fmt: skip
    if len(data["trees"]) > MAX_TREES:
        raise SceneError([{"path": "trees", "message": f"at most {MAX_TREES} trees in one log, got "
                           f"{len(data['trees'])}"}])  # fmt: skip
    errors: list[dict] = []
    trees: list[tuple[int, LoggedTree]] = []
    if not data["trees"]:
        errors.append({"path": "trees", "message": "must list at least one tree"})
    for i, raw in enumerate(data["trees"]):  # each tree on its own, so that every error is said at once
        try:
            trees.append((i, LoggedTree.model_validate(raw)))
        except ValidationError as e:
            errors += [{"path": f"trees[{i}]" + (f".{x['path']}" if x["path"] and not x["path"].startswith("[")
                        else x["path"]), "message": x["message"]} for x in pydantic_errors(e, LoggedTree)]  # fmt: skip
    errors += _structure(trees, width, height)
    if errors:
        raise SceneError(errors)
    return TreeLog.model_construct(trees=[t for _, t in trees])


LOGGED = ("id", "parent", "kind", "origin", "direction", "t", "light", "occluded", "radiance", "weight")


def as_logged(tree: dict) -> dict:
    """A ray tree of the renderer (rendering/raytree.py) as a right tracer logs it: the tree log's fields only
    (what a correct log of that pixel looks like; the tests' right logs)."""
    nodes = []
    for n in tree["nodes"]:
        node = {k: n[k] for k in LOGGED}
        if n.get("hit"):
            node["hit"] = {k: n["hit"][k] for k in ("point", "normal", "object")}
        if n.get("terms"):
            node["terms"] = {k: n["terms"][k] for k in ("ambient", "diffuse", "specular")}
        nodes.append(node)
    return {"pixel": list(tree["pixel"]), "color": tree["color"], "nodes": nodes}


def validate(obj: Any, width: int | None = None, height: int | None = None) -> list[dict]:
    """The errors of a tree log ({path, message} each; [] when it is valid)."""
    try:
        parse(obj, width, height)
    except SceneError as e:
        return e.errors
    return []
