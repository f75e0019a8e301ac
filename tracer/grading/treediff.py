"""Two ray trees of one pixel sample, compared: the student's scene and the reference's, traced with the same
settings and seed (so their eye rays are the same ray), and the first node where they differ, with why.

A ray tree is the format of docs/scene-format.md ("The ray tree"): a flat list of nodes, each with its `parent`.
A node is located by its **path**: the child indices from the root, where a node's children are the nodes
whose `parent` is its id, in the order of their ids (the tracer's depth-first order). [] is the eye ray,
[0] its first child, [2, 0] the first child of its third.

The trees are walked together from the eye ray. Children are paired by what they are, not by their place:
a shadow ray by the light it goes to (the n-th shadow ray towards light 3 with the n-th of the other tree),
a reflection ray with the reflection ray, a transmission ray with the transmission ray. At each pair, in
this order (the order a cause shows itself first):
1. the eye ray's origin and direction ("camera": the cameras differ);
2. what the ray hit ("object": another surface, or one hits and the other leaves the scene);
3. its weight ("weight": the product of kr or kt from the eye);
4. its shadow rays, one by one ("missing": a light that one tree has and the other does not reach;
   "light": towards another place; "shadow": blocked in one and not in the other);
5. the local terms at the hit ("material": diffuse, specular, ambient or emission differ at the same hit);
6. what its shadow rays carry ("light": the light's contribution at the same place differs);
7. its reflection and transmission rays, each compared whole (depth first) before the next
   ("missing": a ray one tree has and the other not);
8. what it carries back ("background": two rays that leave the scene bring back different colours;
   "radiance": anything else, such as fog).
The first difference found is the answer; None when the trees agree everywhere (within TOLERANCE).
"""

from __future__ import annotations

from collections.abc import Iterable

RELATIVE = 1e-3  # two numbers agree when they differ by at most this share of the larger ...
ABSOLUTE = 1e-4  # ... plus this (float noise of two traces of different scenes through the same code)
TERMS = (  # the local terms of a hit (the ray tree's `terms`), the most telling first, and what sets each
    ("diffuse", "kd: its colour"),
    ("specular", "ks or shininess"),
    ("ambient", "ka, which is kd unless set, or the scene's ambient"),
    ("emission", "emission"),
)


def _close(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    xs = a if isinstance(a, list | tuple) else [a]
    ys = b if isinstance(b, list | tuple) else [b]
    if len(xs) != len(ys):
        return False
    return all(abs(x - y) <= ABSOLUTE + RELATIVE * max(abs(x), abs(y)) for x, y in zip(xs, ys, strict=True))


def _num(x) -> str:
    if isinstance(x, list | tuple):
        if len(set(x)) == 1:
            return _num(x[0])
        return "(" + ", ".join(_num(v) for v in x) + ")"  # an RGB triple, as the ray tree's text shows one
    return f"{x:.3g}"


class _Tree:
    """A ray tree's nodes with their children (in id order) and each node's path."""

    def __init__(self, tree: dict):
        nodes = tree.get("nodes") or []
        self.by_id = {n["id"]: n for n in nodes}
        self.children: dict[int, list[dict]] = {n["id"]: [] for n in nodes}
        self.root = None
        for n in sorted(nodes, key=lambda n: n["id"]):
            if n.get("parent") is None:
                self.root = self.root or n
            elif n["parent"] in self.children:
                self.children[n["parent"]].append(n)
        self.paths: dict[int, list[int]] = {}
        if self.root is not None:
            stack = [(self.root, [])]
            while stack:
                n, path = stack.pop()
                self.paths[n["id"]] = path
                stack += [(c, [*path, i]) for i, c in enumerate(self.children[n["id"]])]

    def keyed(self, node: dict) -> dict[tuple, dict]:
        """A node's children by what they are: ("shadow", light, n) or (kind, n), in id order."""
        out, seen = {}, {}
        for c in self.children[node["id"]]:
            base = ("shadow", c.get("light")) if c["kind"] == "shadow" else (c["kind"],)
            seen[base] = seen.get(base, -1) + 1
            out[(*base, seen[base])] = c
        return out


def path_of(tree: dict, node_id: int) -> list[int]:
    """The path (child indices from the root) of the node with this id."""
    return _Tree(tree).paths[node_id]


def node_at(tree: dict, path: Iterable[int]) -> dict:
    """The node at a path (IndexError when there is none)."""
    t = _Tree(tree)
    n = t.root
    if n is None:
        raise IndexError("the tree has no nodes")
    for i in path:
        n = t.children[n["id"]][i]
    return n


def ray_words(n: dict) -> str:
    """'eye ray', 'reflection ray (depth 2)', 'shadow ray towards light 0'."""
    if n["kind"] == "shadow":
        return f"shadow ray towards light {n.get('light')}"
    if n["kind"] == "eye":
        return "eye ray"
    return f"{n['kind']} ray (depth {n['depth']})"


def _hit_words(n: dict) -> str:
    hit = n.get("hit")
    if not hit:
        return "leaves the scene"
    name = hit.get("object_name")
    what = f"'{name}' (object {hit.get('object')})" if name else f"object {hit.get('object')}"
    if hit.get("object") is None and hit.get("light") is not None:
        what = f"light {hit['light']}"
    return f"hits {what} at t = {_num(n['t'])}"


def _where(n: dict) -> str:
    hit = n.get("hit") or {}
    name = hit.get("object_name") or (f"object {hit['object']}" if hit.get("object") is not None else "the surface")
    material = f" (material '{hit['material']}')" if hit.get("material") else ""
    return f"{name}{material}" if hit else "there"


class _Found(Exception):
    def __init__(self, s: dict | None, r: dict | None, what: str, message: str, s_at: dict, r_at: dict):
        self.args = (s, r, what, message)
        self.s_at, self.r_at = s_at, r_at  # the nodes to mark (a missing ray's parent on the side without it)


def first_difference(student: dict, reference: dict) -> dict | None:
    """The first node where two ray trees of one pixel sample differ (the module's order), or None:
    {"student": path, "reference": path, "what", "message", "nodes": {"student": id, "reference": id}}.
    For a ray that only one tree has, the other side's path and id are those of its parent there (the ray
    that did not spawn it)."""
    s, r = _Tree(student), _Tree(reference)
    if s.root is None or r.root is None:
        if s.root is None and r.root is None:
            return None
        raise ValueError("a ray tree without nodes")
    try:
        _pair(s, r, s.root, r.root)
    except _Found as f:
        what, message = f.args[2], f.args[3]
        return {
            "student": s.paths[f.s_at["id"]],
            "reference": r.paths[f.r_at["id"]],
            "what": what,
            "message": message,
            "nodes": {"student": f.s_at["id"], "reference": f.r_at["id"]},
        }
    return None


def _differ(a: dict, b: dict, what: str, message: str):
    raise _Found(a, b, what, message, a, b)


def _pair(s: _Tree, r: _Tree, a: dict, b: dict) -> None:
    """Compare one pair of nodes (a: the student's, b: the reference's) and what hangs below them."""
    ray = ray_words(a)
    if a["kind"] == "eye" and not (
        _close(a.get("origin"), b.get("origin")) and _close(a.get("direction"), b.get("direction"))
    ):
        _differ(
            a,
            b,
            "camera",
            "Your eye ray starts elsewhere or goes another way than the reference's: the "
            "camera differs (lookfrom, lookat, vup, vfov, or the film's size).",
        )
    if a["kind"] != "shadow":
        ha, hb = a.get("hit"), b.get("hit")
        same = (ha is None and hb is None) or (
            ha is not None
            and hb is not None
            and _close(a.get("t"), b.get("t"))
            and _close(ha.get("normal"), hb.get("normal"))
        )
        if not same:
            _differ(
                a,
                b,
                "object",
                f"Your {ray} {_hit_words(a)}; the reference's {_hit_words(b)}: another object is "
                "there (check the objects' places and sizes).",
            )
    if not _close(a.get("weight"), b.get("weight")):
        parent = s.by_id.get(a.get("parent"))
        at = f" at {_where(parent)}" if parent else ""
        term = {"reflection": "kr", "transmission": "kt"}.get(a["kind"], "kr or kt")
        _differ(
            a,
            b,
            "weight",
            f"Your {ray} carries weight {_num(a['weight'])}; the reference's "
            f"{_num(b['weight'])}: the material{at} reflects or transmits another share (its {term}, or fresnel).",
        )
    if a["kind"] == "shadow":
        return
    ka, kb = s.keyed(a), r.keyed(b)
    shadows = sorted(
        {k for k in (*ka, *kb) if k[0] == "shadow"}, key=lambda k: (k[1] if k[1] is not None else -1, k[2])
    )
    for k in shadows:
        _missing(a, b, ka.get(k), kb.get(k))
        x, y = ka[k], kb[k]
        if not _close(x.get("direction"), y.get("direction")):
            _differ(
                x,
                y,
                "light",
                f"Your {ray_words(x)} from {_where(a)} goes another way than the reference's: the light is elsewhere.",
            )
        if bool(x.get("occluded")) != bool(y.get("occluded")):
            mine = f"is blocked by {_blocker(x)}" if x.get("occluded") else "reaches the light"
            theirs = f"is blocked by {_blocker(y)}" if y.get("occluded") else "reaches it"
            _differ(
                x,
                y,
                "shadow",
                f"Your {ray_words(x)} from {_where(a)} {mine}; the reference's {theirs}: "
                "an object casts another shadow here.",
            )
    ta, tb = a.get("terms") or {}, b.get("terms") or {}
    differ = [
        (term, field, ta.get(term) or [0.0] * 3, tb.get(term) or [0.0] * 3)
        for term, field in TERMS
        if not _close(ta.get(term) or [0.0] * 3, tb.get(term) or [0.0] * 3)
    ]
    if differ:
        terms = "; ".join(f"{term} {_num(x)} against {_num(y)}" for term, _, x, y in differ)
        fields = ", ".join(field for _, field, _, _ in differ)
        _differ(
            a,
            b,
            "material",
            f"Where your {ray} hits {_where(a)}, as the reference's does, the light it reflects there differs "
            f"(yours against the reference's): {terms}. The material differs ({fields}), or a light's intensity.",
        )
    for k in shadows:
        x, y = ka[k], kb[k]
        if not _close(x.get("radiance"), y.get("radiance")):
            _differ(
                x,
                y,
                "light",
                f"Your {ray_words(x)} from {_where(a)} brings {_num(x['radiance'])}; the "
                f"reference's {_num(y['radiance'])}: the light's intensity or fall-off differs.",
            )
    ordered = [k for k in kb if k[0] != "shadow"] + [k for k in ka if k[0] != "shadow" and k not in kb]
    for k in ordered:
        _missing(a, b, ka.get(k), kb.get(k))
        _pair(s, r, ka[k], kb[k])
    if not _close(a.get("radiance"), b.get("radiance")):
        if a.get("hit") is None:
            _differ(
                a,
                b,
                "background",
                f"Your {ray} leaves the scene, as the reference's does, but brings back "
                f"{_num(a['radiance'])} where the reference's brings {_num(b['radiance'])}: the background "
                "(or the fog) differs.",
            )
        _differ(
            a,
            b,
            "radiance",
            f"Your {ray} brings back {_num(a['radiance'])}; the reference's "
            f"{_num(b['radiance'])}, though every ray below it agrees (the fog, or the light's emission).",
        )


def _blocker(n: dict) -> str:
    hit = n.get("hit") or {}
    return (
        f"'{hit['object_name']}'"
        if hit.get("object_name")
        else (f"object {hit['object']}" if hit.get("object") is not None else "an object")
    )


def _missing(a: dict, b: dict, x: dict | None, y: dict | None) -> None:
    """A child one tree has and the other not: the difference, marked on the child and on the other's parent."""
    if x is not None and y is not None:
        return
    n = x or y
    assert n is not None, "one of the two trees has the child"
    why = {
        "shadow": "a light that one scene has, or that cannot light this point in the other (behind the surface, "
        "outside a spot's cone)",
        "reflection": "kr, max_depth or min_weight",
        "transmission": "kt, max_depth, min_weight, or total internal reflection (ior)",
    }.get(n["kind"], "the materials")
    if x is None:
        assert y is not None, "one of the two trees has the child"
        message = f"The reference's {_where(b)} casts a {ray_words(y)}; yours, at {_where(a)}, does not (check {why})."
        raise _Found(None, y, "missing", message, a, y)
    message = f"Your {_where(a)} casts a {ray_words(x)}; the reference's, at {_where(b)}, does not (check {why})."
    raise _Found(x, None, "missing", message, x, b)
