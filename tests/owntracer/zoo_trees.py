"""Whether two ray trees of one pixel are the same, node by node: the tests' yardstick for the bug zoo.

Not the service's feedback (tracer/grading/explain.py names *what* differs); only where two trees first
part, as a path of nodes, or None. A tree is a dict with "nodes" (the tree log's or the ray tree's format):
children are paired by kind, a shadow ray by its light (the n-th shadow ray to light 1 with the other's
n-th), so two tracers may log a node's children in another order.
"""

from __future__ import annotations

import math

# Where a bug shows: more than float noise; the 1e-4 spawn offset and what it moves downstream (a hit point, the
# normal there) are not a difference.
POSITION = 1e-3  # world units: origins, hit points, distances t differ by at most this ...
POSITION_REL = 1e-4  # ... plus this share of their size (a float32 tracer's far hits near the horizon)
DIRECTION = 1e-3  # unit vectors: directions, normals (component-wise)
RELATIVE = 1e-3  # colours: weights, radiance, terms differ by at most this share of the larger ...
ABSOLUTE = 1e-5  # ... plus this


def _close(a, b, rel: float, abs_: float) -> bool:
    return all(abs(x - y) <= abs_ + rel * max(abs(x), abs(y)) for x, y in zip(a, b, strict=True))


def _unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def _children(nodes: list[dict]) -> dict:
    """Each node's children by (kind, light), in the order of their ids."""
    out: dict = {}
    for n in nodes:
        if n.get("parent") is not None:
            key = (n["kind"], n.get("light") if n["kind"] == "shadow" else None)
            out.setdefault(n["parent"], {}).setdefault(key, []).append(n)
    return out


def node_difference(
    a: dict,
    b: dict,
    position=POSITION,
    position_rel=POSITION_REL,
    direction=DIRECTION,
    rel=RELATIVE,
    abs_=ABSOLUTE,
    radiance=True,
):
    """What differs between two nodes (their own fields, not their children; `radiance` False: all but
    what the ray carries back, which its subtree sets), or None."""

    def near(u, v):
        return _close(u, v, position_rel, position)

    if a["kind"] != b["kind"]:
        return f"kind {a['kind']} != {b['kind']}"
    if not near(a["origin"], b["origin"]):
        return f"origin {a['origin']} != {b['origin']}"
    if not _close(_unit(a["direction"]), _unit(b["direction"]), 0.0, direction):
        return f"direction {a['direction']} != {b['direction']}"
    if a["kind"] == "shadow" and (a.get("light"), bool(a.get("occluded"))) != (b.get("light"), bool(b.get("occluded"))):
        return f"light, occluded {a.get('light')}, {a.get('occluded')} != {b.get('light')}, {b.get('occluded')}"
    if (a.get("t") is None) != (b.get("t") is None):
        return f"t {a.get('t')} != {b.get('t')}"
    if a.get("t") is not None and not near([a["t"]], [b["t"]]):
        return f"t {a['t']} != {b['t']}"
    ha, hb = a.get("hit"), b.get("hit")
    if (ha is None) != (hb is None):
        return f"hit {ha} != {hb}"
    if ha is not None:
        if ha.get("object") != hb.get("object"):
            return f"hit object {ha.get('object')} != {hb.get('object')}"
        if not near(ha["point"], hb["point"]):
            return f"hit point {ha['point']} != {hb['point']}"
        if not _close(ha["normal"], hb["normal"], 0.0, direction):
            return f"normal {ha['normal']} != {hb['normal']}"
    for key in ("weight", "radiance") if radiance else ("weight",):
        if a.get(key) is not None and b.get(key) is not None and not _close(a[key], b[key], rel, abs_):
            return f"{key} {a[key]} != {b[key]}"
    ta, tb = a.get("terms"), b.get("terms")
    if ta and tb:
        for key in ("ambient", "diffuse", "specular"):
            if not _close(ta[key], tb[key], rel, abs_):
                return f"terms.{key} {ta[key]} != {tb[key]}"
    return None


def tree_difference(a: dict, b: dict, **tolerances) -> str | None:
    """Where trees a and b first differ ("eye > reflection > shadow(light 1): occluded ..."), or None: the
    rays first, depth first, then what each carries back (the cause comes before the colours it changes)."""
    return _walk(a, b, radiance=False, **tolerances) or _walk(a, b, radiance=True, **tolerances)


def _walk(a: dict, b: dict, **tolerances) -> str | None:
    ka, kb = _children(a["nodes"]), _children(b["nodes"])
    roots_a = [n for n in a["nodes"] if n.get("parent") is None]
    roots_b = [n for n in b["nodes"] if n.get("parent") is None]
    if len(roots_a) != 1 or len(roots_b) != 1:
        return f"{len(roots_a)} and {len(roots_b)} eye rays"
    stack = [(roots_a[0], roots_b[0], "eye")]
    while stack:
        na, nb, path = stack.pop()
        why = node_difference(na, nb, **tolerances)
        if why:
            return f"{path}: {why}"
        ca, cb = ka.get(na["id"], {}), kb.get(nb["id"], {})
        for key in sorted(set(ca) | set(cb), key=str, reverse=True):
            la, lb = ca.get(key, []), cb.get(key, [])
            name = key[0] if key[1] is None else f"{key[0]}(light {key[1]})"
            if len(la) != len(lb):
                return f"{path} > {name}: {len(la)} != {len(lb)} rays"
            stack.extend((x, y, f"{path} > {name}") for x, y in reversed(list(zip(la, lb, strict=True))))
    return None
