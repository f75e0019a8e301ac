"""A student's own ray tracer, explained: each tree of their tree log (treelog.py) compared with the reference's
tree through the same pixel's centre, and the first difference named in the lecture's words (docs/own-tracer.md).

The reference tree is traced by the renderer's own kernels (rendering/raytree.py): the reference scene as the
Whitted integrator renders it, with its max_depth and min_weight, through the pixel's centre (the `center`
sampler), with a pinhole. Trees are walked together from the eye ray; a node's children are paired by what they
are (a shadow ray by its light, then the n-th reflection ray with the n-th, the n-th transmission ray likewise),
never by their order, and numbers agree within a tolerance of float noise (a student's tracer may compute in
float32 or float64, and offset its rays by another small epsilon).

At each pair, in this order (the order in which a cause shows itself first):
1. the eye ray's origin and direction (`eye_ray`);
2. a reflection or transmission ray's direction (`reflection_direction`, `refraction_direction`);
3. what the ray hit, and where (`hit`), then the normal there (`normal`);
4. its shadow rays, each: blocked at a tiny t by the surface it leaves (`shadow_acne`), blocked or not against
   the reference (`shadow`), what it brings (`attenuation` when it is off by the light's f_att, else `shading`);
5. the local terms at the hit (`shading`);
6. its reflection and transmission rays: total internal reflection (`total_internal_reflection`), the depth
   limit (`depth`), their weights (`fresnel`), rays one tree has and the other not (`missing_ray`,
   `extra_ray`), then each child whole, depth first;
7. what it carries back (`shading`);
8. at the root, when the whole tree agrees: the image's pixel against the tree's colour (`encoding`).
A difference in a ray's direction or hit ends the walk below that ray (what follows would differ anyway); the
walk goes on in the other branches, so one pixel can show several differences, the first one first. A ray that
grazes a surface hits it where a turn of its direction within float noise moves the hit far along the surface:
such a hit agrees within that distance, and what follows from it is not compared.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from tracer.grading.treelog import TreeLog, parse

WHATS = (
    "eye_ray", "hit", "normal", "shadow_acne", "shadow", "reflection_direction", "refraction_direction",
    "total_internal_reflection", "fresnel", "shading", "attenuation", "depth", "missing_ray", "extra_ray", "encoding",
)  # fmt: skip
EYE_ANGLE = 1e-4  # radians: eye rays agree within this (float32 noise is ~1e-7; half a pixel of 1024 is ~7e-4)
RAY_ANGLE = 2e-3  # radians: secondary and shadow rays (their origins carry the offsets of earlier hits)
RELATIVE = 0.01  # colours and weights agree within this share of the larger ...
ABSOLUTE = 2e-3  # ... plus this
PIXEL = 3.0 / 255.0  # an image's pixel agrees with its tree's colour within this (8-bit rounding, noise)
MAX_DIFFERENCES = 8  # differences reported per tree


def _v(x) -> np.ndarray:
    return np.asarray(x, dtype=np.float64)


def _unit(x) -> np.ndarray:
    v = _v(x)
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


def _angle(a, b) -> float:
    c = float(np.clip(np.dot(_unit(a), _unit(b)), -1.0, 1.0))
    return math.acos(c)


def _p(x) -> str:
    """(0.2, 0, 1.3): a point or a colour as the messages show it."""
    return "(" + ", ".join(f"{c:.3g}" if abs(c) >= 5e-4 else "0" for c in _v(x)) + ")"


def _close(a, b, rel: float = RELATIVE, abs_: float = ABSOLUTE) -> bool:
    a, b = _v(a), _v(b)
    return bool(np.all(np.abs(a - b) <= abs_ + rel * np.maximum(np.abs(a), np.abs(b))))


def _srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


@dataclass
class _Walk:
    """One tree's comparison under way: the differences found, the reference scene's facts."""

    ex: Explainer
    student: dict[int, dict]  # id -> node
    s_kids: dict[int, list[dict]]
    reference: dict[int, dict]
    r_kids: dict[int, list[dict]]
    found: list[dict] = field(default_factory=list)

    def add(self, what: str, message: str, s: dict | None, r: dict | None) -> None:
        assert what in WHATS, what
        if len(self.found) < MAX_DIFFERENCES:
            self.found.append(
                {"what": what, "message": message, "student": None if s is None else s["id"],
                 "reference": None if r is None else r["id"]}
            )  # fmt: skip


class Explainer:
    """The reference's centre-ray trees of one scene, and the comparison of a tree log with them.

    ex = Explainer(reference_scene_dict)
    answers = ex.compare(log, image)   # one answer per logged tree (the contract's shape)
    """

    def __init__(self, scene: dict, reference_shown: np.ndarray | None = None, device: str | None = "cpu"):
        """`scene`: the reference scene (a dict of the scene format, the assignment's settings applied);
        `reference_shown`: its picture as shown (H, W, 3, sRGB floats in [0, 1]), when there is one, for the
        `encoding` check; `device`: where its trees are traced (None: they are handed to `compare`, traced
        elsewhere from `centre_scene(scene)`, as the service's workers do)."""
        from tracer.scene import load_scene

        self.scene, _ = load_scene(centre_scene(scene))
        self.cs = None
        if device is not None:
            from tracer.kernels.compile import compile_scene

            self.cs = compile_scene(self.scene, device=device)
        self.device = device
        self.width, self.height = self.scene.film.width, self.scene.film.height
        self.exposure = float(self.scene.film.exposure)
        self.reference_shown = reference_shown
        cam = self.scene.camera
        self.lookfrom = _v(cam.lookfrom)
        self.scale = max(1.0, float(np.linalg.norm(_v(cam.lookat) - self.lookfrom)))
        self.position = 2e-3 * self.scale  # points agree within this (a tracer's offset may be 1e-3)
        self.acne = 1e-3 * self.scale  # a shadow ray blocked nearer than this by its own surface: acne
        self.names = [o.name for o in self.scene.objects]
        self._trees: dict[tuple[int, int], dict] = {}

    # -- the reference

    def reference_tree(self, x: int, y: int) -> dict:
        """The reference's tree of the ray through the centre of pixel (x, y) (kept once traced)."""
        from tracer.rendering.raytree import ray_tree

        if (x, y) not in self._trees:
            if self.cs is None or self.device is None:  # both None, or neither
                raise LookupError(f"no reference tree at ({x}, {y}) was handed over")
            self._trees[x, y] = ray_tree(self.cs, x, y, 0, device=self.device)
        return self._trees[x, y]

    def camera_frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        cam = self.scene.camera
        forward = _unit(_v(cam.lookat) - self.lookfrom)
        right = _unit(np.cross(forward, _v(cam.vup)))
        up = np.cross(right, forward)
        h = math.tan(math.radians(cam.vfov) / 2)
        return forward, right, up, h, self.width / self.height

    def film_position(self, direction) -> tuple[float, float] | None:
        """Where an eye ray from lookfrom in this direction crosses the film, in pixels (x + u, y + v)."""
        forward, right, up, h, aspect = self.camera_frame()
        d = _unit(direction)
        f = float(np.dot(d, forward))
        if f <= 1e-9:
            return None
        sx, sy = float(np.dot(d, right)) / f / (h * aspect), float(np.dot(d, up)) / f / h
        return (sx + 1) / 2 * self.width, (1 - sy) / 2 * self.height

    # -- the comparison

    def compare(
        self, log: TreeLog | dict | bytes | str, image: np.ndarray | None = None, trees: dict | None = None
    ) -> list[dict]:
        """Each logged tree against the reference's at its pixel: {pixel, matches, differences: [{what, message,
        student: node id, reference: node id}], student: the logged tree, reference: the reference's tree}.
        `image`: the student's picture as shown (H, W, 3), floats in [0, 1] (sRGB) or uint8, for `encoding`;
        `trees`: the reference's trees traced elsewhere, by (x, y)."""
        self._trees.update(trees or {})
        if not isinstance(log, TreeLog):
            log = parse(log, self.width, self.height)
        if image is not None and image.dtype == np.uint8:
            image = image.astype(np.float64) / 255.0
        out = []
        for tree in log.trees:
            mine = tree.model_dump(mode="json", exclude_none=False)
            x, y = tree.pixel
            ref = self.reference_tree(x, y)
            differences = self.differences(mine, ref, image)
            out.append({"pixel": [x, y], "matches": not differences, "differences": differences,
                        "student": mine, "reference": ref})  # fmt: skip
        return out

    def differences(self, mine: dict, ref: dict, image: np.ndarray | None = None) -> list[dict]:
        s_nodes = {n["id"]: n for n in mine["nodes"]}
        r_nodes = {n["id"]: n for n in ref["nodes"]}
        walk = _Walk(self, s_nodes, _children(mine["nodes"]), r_nodes, _children(ref["nodes"]))
        s_root = next(n for n in mine["nodes"] if n["parent"] is None)
        r_root = next(n for n in ref["nodes"] if n["parent"] is None)
        _pair(walk, s_root, r_root, 1)
        if not walk.found and image is not None:
            self._encoding(walk, mine, ref, image, s_root, r_root)
        return walk.found

    def _encoding(self, walk: _Walk, mine: dict, ref: dict, image: np.ndarray, s: dict, r: dict) -> None:
        x, y = mine["pixel"]
        if image.shape[:2] != (self.height, self.width):
            return
        color = _v(ref["color"])
        shown = _v(image[y, x, :3])
        expected = _srgb(color * 2.0**self.exposure)
        if np.all(np.abs(shown - expected) <= PIXEL):
            return
        if self.reference_shown is not None and self.reference_shown.shape[:2] == image.shape[:2]:
            mean = _v(self.reference_shown[y, x, :3])  # a supersampled pixel: the reference's own there
            if np.all(np.abs(shown - mean) <= PIXEL + 0.02):
                return
        scaled = np.clip(color * 2.0**self.exposure, 0, 1)
        guesses = (
            (scaled, "the linear value itself: the sRGB curve (the OETF, about a 1/2.4 power) is missing"),
            (_srgb(color), "the sRGB value without the film's exposure (2^exposure)"),
            (np.power(scaled, 1 / 2.2), "a plain 1/2.2 power: close, but sRGB has a linear part near black"),
            (np.power(scaled, 1 / 2.4), "a 1/2.4 power without sRGB's scale and offset (1.055 x^(1/2.4) - 0.055)"),
        )  # fmt: skip
        why = next((w for g, w in guesses if np.all(np.abs(shown - g) <= PIXEL)), None)
        said = why or "check the clamp to [0, 1], the exposure and the sRGB curve"
        walk.add(
            "encoding",
            f"Your tree at pixel ({x}, {y}) is right: it brings {_p(color)} (linear), as the reference's does. But "
            f"your image's pixel there is {_p(shown * 255)} of 255 where {_p(expected * 255)} is expected: the "
            f"pixel is written as {said}.",
            s,
            r,
        )


def centre_scene(scene: dict) -> dict:
    """The reference scene as its centre-ray trees are traced: Whitted, one ray through each pixel's centre, a
    pinhole (its max_depth, min_weight, lights and film as they are)."""
    data = copy.deepcopy(scene)
    data["sampler"] = {"type": "center", "spp": 1}
    data.setdefault("render", {})["integrator"] = "whitted"
    data.setdefault("camera", {})["lens_radius"] = 0.0
    return data


def _children(nodes: Iterable[dict]) -> dict[int, list[dict]]:
    out: dict[int, list[dict]] = {n["id"]: [] for n in nodes}
    for n in sorted(nodes, key=lambda n: n["id"]):
        if n["parent"] is not None and n["parent"] in out:
            out[n["parent"]].append(n)
    return out


def _object_words(ex: Explainer, hit: dict | None) -> str:
    if not hit:
        return "nothing"
    obj = hit.get("object")
    if obj is not None and 0 <= obj < len(ex.names):
        name = ex.names[obj]
        return f"'{name}' (object {obj})" if name else f"object {obj}"
    if hit.get("object_name"):
        return f"'{hit['object_name']}'"
    if hit.get("light") is not None:
        return f"light {hit['light']}"
    return "a surface"


def _same_object(ex: Explainer, a: dict | None, b: dict | None) -> bool | None:
    """Whether a student's hit names the reference's object (None when the student names none)."""
    if not a or not b:
        return None
    if a.get("object") is not None:
        return a["object"] == b.get("object")
    if a.get("object_name"):
        return a["object_name"] == b.get("object_name")
    return None


def _ray(n: dict) -> str:
    return {"eye": "eye ray", "shadow": "shadow ray", "reflection": "reflection ray",
            "transmission": "transmission ray"}[n["kind"]]  # fmt: skip


def _from(walk: _Walk, n: dict) -> str:
    """' from the floor at (0.2, 0, 1.3)': where a ray leaves, from its parent's hit."""
    parent = walk.reference.get(n["parent"]) if n.get("parent") is not None else None
    if parent is None or not parent.get("hit"):
        return ""
    return f" from {_object_words(walk.ex, parent['hit'])} at {_p(parent['hit']['point'])}"


def _pair(walk: _Walk, s: dict, r: dict, depth: int) -> None:
    """Compare one pair of rays (s: the student's, r: the reference's at the same place) and what is below."""
    if s["kind"] == "eye":
        if not _eye(walk, s, r):
            return
    elif not _direction(walk, s, r):
        return
    if not _hit(walk, s, r):
        return
    if s["kind"] == "shadow":
        return
    if r.get("hit") is None:
        _carried(walk, s, r)
        return
    _shadows(walk, s, r)
    _terms(walk, s, r)
    _secondary(walk, s, r, depth)
    if not walk.found:
        _carried(walk, s, r)


def _eye(walk: _Walk, s: dict, r: dict) -> bool:
    ex = walk.ex
    if np.linalg.norm(_v(s["origin"]) - _v(r["origin"])) > ex.position:
        walk.add("eye_ray", f"Your eye ray starts at {_p(s['origin'])}; the camera is at lookfrom = "
                 f"{_p(r['origin'])}: every eye ray starts there (a pinhole camera).", s, r)  # fmt: skip
        return False
    angle = _angle(s["direction"], r["direction"])
    if angle <= EYE_ANGLE:
        return True
    mine, theirs = ex.film_position(s["direction"]), ex.film_position(r["direction"])
    message = (f"Your eye ray goes in direction {_p(_unit(s['direction']))}; the reference's in "
               f"{_p(_unit(r['direction']))} ({math.degrees(angle):.3g} degrees apart).")  # fmt: skip
    if mine is not None and theirs is not None:
        (mx, my), (tx, ty) = mine, theirs
        px, py = math.floor(tx), math.floor(ty)
        message += f" Yours crosses the film at ({mx:.2f}, {my:.2f}) in pixels; the ray of pixel ({px}, {py}) " \
                   f"goes through its centre ({tx:.2f}, {ty:.2f})."  # fmt: skip
        cx, cy = ex.width / 2, ex.height / 2
        if abs(mx - (tx - 0.5)) < 0.05 and abs(my - (ty - 0.5)) < 0.05:
            message += " That is the pixel's corner: use (x + 0.5, y + 0.5), the centre, as the film position."
        elif abs(mx - tx) < 0.6 and abs(my - ty) < 0.6:
            message += " That is half a pixel or less off: the film position of pixel (x, y) is (x + 0.5, y + 0.5)" \
                       ", with y from the top."  # fmt: skip
        elif abs(tx - cx) > 1 and abs(ty - cy) > 1:
            kx, ky = (mx - cx) / (tx - cx), (my - cy) / (ty - cy)
            aspect = ex.width / ex.height
            if abs(kx - ky) < 0.02 * max(abs(kx), 1) and abs(kx - 1) > 0.02:
                message += f" Your picture is scaled by {1 / kx:.3g} about its centre: the field of view differs."
                vfov = math.radians(ex.scene.camera.vfov)
                hfov_as_v = math.tan(vfov / 2) / aspect
                if abs(1 / kx * hfov_as_v / math.tan(vfov / 2) - 1) < 0.02 or abs(1 / kx - aspect) < 0.02:
                    message += " vfov is the VERTICAL field of view: h = tan(vfov/2) scales up, h x aspect scales " \
                               "right (aspect = width / height)."  # fmt: skip
            elif abs(kx + 1) < 0.02 or abs(ky + 1) < 0.02:
                message += " Your picture is flipped: y counts rows from the top, so up is (1 - 2(y+0.5)/height)."
    walk.add("eye_ray", message, s, r)
    return False


def _direction(walk: _Walk, s: dict, r: dict) -> bool:
    """A secondary or shadow ray's direction; False (with the difference) when it goes another way."""
    angle = _angle(s["direction"], r["direction"])
    if angle <= RAY_ANGLE:
        return True
    where = _from(walk, r)
    if s["kind"] == "shadow":
        walk.add("shadow", f"Your shadow ray{where} towards light {r.get('light')} goes in direction "
                 f"{_p(_unit(s['direction']))}; towards the light is {_p(_unit(r['direction']))}.", s, r)  # fmt: skip
        return False
    mine, theirs = _p(_unit(s["direction"])), _p(_unit(r["direction"]))
    parent = walk.reference.get(r["parent"])
    incoming = _unit(parent["direction"]) if parent else None
    normal = _unit(parent["hit"]["normal"]) if parent and parent.get("hit") else None
    if s["kind"] == "reflection":
        text = (f"Your reflection ray{where} goes in direction {mine}; the mirror direction is {theirs} "
                f"({math.degrees(angle):.3g} degrees apart). R = D - 2 (D.N) N, with D the incoming direction and N "
                "the unit normal.")  # fmt: skip
        if incoming is not None and normal is not None:
            wrong = incoming + 2 * np.dot(incoming, normal) * normal
            if _angle(s["direction"], wrong) < RAY_ANGLE:
                text += " Yours is D + 2 (D.N) N: the sign of the (D.N) term is flipped."
            elif _angle(s["direction"], -_unit(r["direction"])) < RAY_ANGLE:
                text += " Yours points back the opposite way: check which way D points (towards the surface)."
        walk.add("reflection_direction", text, s, r)
        return False
    text = (f"Your transmission ray{where} goes in direction {mine}; the refracted direction is {theirs} "
            f"({math.degrees(angle):.3g} degrees apart). Snell: n1 sin(theta1) = n2 sin(theta2), with eta = n1 / n2 "
            "(from 1 to ior entering a front face, from ior to 1 leaving).")  # fmt: skip
    if incoming is not None and normal is not None and parent and parent.get("hit"):
        front = parent["hit"].get("front_face", True)
        ior = _ior(walk.ex, parent["hit"])
        if ior is not None:
            eta = 1 / ior if front else ior
            flipped = _refract(incoming, normal, 1 / eta)
            if flipped is not None and _angle(s["direction"], flipped) < RAY_ANGLE:
                text += (f" Yours bends with eta = {1 / eta:.3g}, the inverse: n2 / n1 in place of n1 / n2"
                         f" ({'entering' if front else 'leaving'} the surface here).")  # fmt: skip
    walk.add("refraction_direction", text, s, r)
    return False


def _refract(d: np.ndarray, n: np.ndarray, eta: float) -> np.ndarray | None:
    cos_i = -float(np.dot(d, n))
    k = 1 - eta * eta * (1 - cos_i * cos_i)
    if k < 0:
        return None
    return eta * d + (eta * cos_i - math.sqrt(k)) * n


def _material(ex: Explainer, hit: dict | None):
    obj = (hit or {}).get("object")
    if obj is None or not 0 <= obj < len(ex.scene.objects):
        return None
    m = ex.scene.objects[obj].material
    if isinstance(m, str):
        return ex.scene.materials.get(m)
    return m


def _ior(ex: Explainer, hit: dict) -> float | None:
    m = _material(ex, hit)
    return None if m is None else float(m.ior)


def _hit(walk: _Walk, s: dict, r: dict) -> bool:
    """What the ray hit (for a shadow ray: what blocked it); False when the walk stops below it."""
    ex = walk.ex
    if s["kind"] == "shadow":
        return _shadow(walk, s, r)
    ts, tr = s.get("t"), r.get("t")
    where = _from(walk, r)
    ray = "eye ray" if s["kind"] == "eye" else _ray(s) + where
    if ts is None and tr is None:
        return True
    if ts is None or tr is None:
        mine = "leaves the scene" if ts is None else f"hits {_object_words(ex, s.get('hit'))} at t = {ts:.4g}"
        theirs = "leaves the scene" if tr is None else f"hits {_object_words(ex, r.get('hit'))} at t = {tr:.4g}"
        walk.add("hit", f"Your {ray} {mine}; the reference's {theirs}.", s, r)
        return False
    same = _same_object(ex, s.get("hit"), r.get("hit"))
    # a ray that grazes a surface meets it much further on for a tiny turn of its direction: the same object's
    # hit agrees within the distance its direction's noise (RAY_ANGLE) moves it along the surface
    graze = abs(float(np.dot(_unit(r["direction"]), _unit((r.get("hit") or {}).get("normal") or [0, 0, 1]))))
    slack = tr * (1e-3 + (RAY_ANGLE / max(graze, 1e-3) if same is not False and s["kind"] != "eye" else 0.0))
    if same is False or abs(ts - tr) > ex.position + slack:
        mine = f"hits {_object_words(ex, s.get('hit'))} at t = {ts:.4g}"
        theirs = f"hits {_object_words(ex, r.get('hit'))} at t = {tr:.4g}"
        text = f"Your {ray} {mine}; the reference's {theirs}."
        parent = walk.reference.get(up) if (up := r.get("parent")) is not None else None
        if ts < ex.acne and parent is not None and _same_object(ex, s.get("hit"), parent.get("hit")) is not False:
            text += (" It hits the surface it leaves, at once: offset the new ray's origin along the normal "
                     "(hit + 1e-4 N, N turned to the side the ray goes), as for shadow acne.")  # fmt: skip
        elif same is not False and abs(ts - tr) > ex.position:
            text += " The same object at another distance: check its intersection (the nearer root, t > 0)."
        elif same is False and abs(ts - tr) <= ex.position + 1e-3 * tr:
            text += (" Both at the same distance: two surfaces meet there (coplanar, or touching), and which one a "
                     "ray hits is a tie of rounding; the scene should keep them apart.")  # fmt: skip
        walk.add("hit", text, s, r)
        return False
    hs, hr = s.get("hit") or {}, r.get("hit") or {}
    if abs(ts - tr) > ex.position + 1e-3 * tr:
        return False  # a grazing hit, the same within its direction's noise: what follows from it is not compared
    if hs.get("point") is not None and np.linalg.norm(_v(hs["point"]) - _v(hr["point"])) > ex.position + 1e-3 * tr:
        walk.add("hit", f"Your {ray} hits at {_p(hs['point'])}; the reference's at {_p(hr['point'])} "
                 f"(t = {tr:.4g}): the hit point is origin + t x direction.", s, r)  # fmt: skip
        return False
    if hs.get("normal") is not None and _angle(hs["normal"], hr["normal"]) > RAY_ANGLE:
        name = _object_words(ex, hr)
        text = f"Your normal at {name} at {_p(hr['point'])} is {_p(_unit(hs['normal']))}; the reference's is " \
               f"{_p(_unit(hr['normal']))}."  # fmt: skip
        if _angle(hs["normal"], -_unit(hr["normal"])) < RAY_ANGLE:
            inside = not hr.get("front_face", True)
            text += (" Yours points the other way" + (": the ray is inside the object, and the normal must be turned"
                     " to face the ray (front_face false: N = -N, and eta = ior / 1)." if inside else
                     ": the normal is turned to face the incoming ray (all surfaces are two-sided)."))  # fmt: skip
        walk.add("normal", text, s, r)
        return False
    return True


def _shadow(walk: _Walk, s: dict, r: dict) -> bool:
    """A shadow ray's fate: blocked or reaching its light."""
    ex = walk.ex
    blocked_s = bool(s.get("occluded")) if s.get("occluded") is not None else s.get("t") is not None
    blocked_r = bool(r.get("occluded"))
    parent = walk.reference.get(r["parent"])
    where = f" from {_object_words(ex, parent['hit'])} at {_p(parent['hit']['point'])}" if parent else ""
    light = f"light {r.get('light')}"
    t = s.get("t")
    own = parent is not None and _same_object(ex, s.get("hit"), parent.get("hit")) is not False
    acne = blocked_s and t is not None and t < ex.acne and own
    if blocked_s == blocked_r and not (acne and (r.get("t") or 0.0) >= ex.acne):
        return True
    if blocked_s:
        if acne and parent is not None:  # acne: its own surface, the parent's
            walk.add("shadow_acne", f"Your shadow ray{where} is blocked at t = {t:.2g} by "
                     f"{_object_words(ex, s.get('hit') or parent['hit'])}, the surface it leaves: shadow acne. Offset "
                     "its origin along the normal (hit + 1e-4 N, N turned towards the light), or the ray meets its own"
                     " surface again through rounding.", s, r)  # fmt: skip
            return False
        by = f" by {_object_words(ex, s.get('hit'))}" + (f" at t = {t:.4g}" if t is not None else "")
        walk.add("shadow", f"Your shadow ray{where} towards {light} is blocked{by}; the reference's reaches the "
                 "light: nothing is between them (only surfaces nearer than the light block it).", s, r)  # fmt: skip
        return False
    walk.add("shadow", f"Your shadow ray{where} towards {light} reaches the light; the reference's is blocked by "
             f"{_object_words(ex, r.get('hit'))} at t = {r.get('t') or 0:.4g}: this point is in shadow (a shadow "
             "ray is blocked by any surface nearer than the light, transparent or not).", s, r)  # fmt: skip
    return False


def _light(ex: Explainer, index: int | None):
    if index is None or not 0 <= index < len(ex.scene.lights):
        return None
    return ex.scene.lights[index]


def _f_att(light, point) -> tuple[float, float] | None:
    """(f_att, d) of a point or spot light at a point."""
    if light is None or light.type not in ("point", "spot"):
        return None
    d = float(np.linalg.norm(_v(light.position) - _v(point)))
    c1, c2, c3 = light.attenuation
    return 1.0 / (c1 + c2 * d + c3 * d * d), d


def _shadows(walk: _Walk, s: dict, r: dict) -> None:
    """The shadow rays of a hit, paired by light (or by direction when the student names none)."""
    ex = walk.ex
    area = {i for i, lt in enumerate(ex.scene.lights) if lt.type in ("quad", "disk", "sphere")}
    mine = [c for c in walk.s_kids[s["id"]] if c["kind"] == "shadow"]
    theirs = [c for c in walk.r_kids[r["id"]] if c["kind"] == "shadow" and c.get("light") not in area]
    pairs, left = [], list(theirs)
    for c in mine:
        if c.get("light") in area:
            continue
        if c.get("light") is not None:
            match = next((x for x in left if x.get("light") == c["light"]), None)
        else:
            match = min(left, key=lambda x: _angle(x["direction"], c["direction"]), default=None)
            if match is not None and _angle(match["direction"], c["direction"]) > 0.2:
                match = None
        if match is None:
            if c.get("radiance") is not None and max(c["radiance"]) > ABSOLUTE:
                walk.add("extra_ray", f"Your shadow ray{_from(walk, r)} towards light {c.get('light')} brings "
                         f"{_p(c['radiance'])}; the reference casts none there: that light cannot light this point "
                         "(behind the surface: N.L <= 0, or outside a spot's cone).", c, r)  # fmt: skip
            continue
        left.remove(match)
        pairs.append((c, match))
    for x in left:
        walk.add("missing_ray", f"The reference casts a shadow ray{_from(walk, x)} towards light {x.get('light')}; "
                 "yours casts none: each light that can light the point (N.L > 0) gets one.", s, x)  # fmt: skip
    for c, x in pairs:
        if not _direction(walk, c, x) or not _shadow(walk, c, x):
            continue
        if c.get("radiance") is None or _close(c["radiance"], x["radiance"]):
            continue
        _brought(walk, s, r, c, x)


def _brought(walk: _Walk, s: dict, r: dict, c: dict, x: dict) -> None:
    """A shadow ray that brings another contribution than the reference's."""
    ex = walk.ex
    light = _light(ex, x.get("light"))
    point = r["hit"]["point"]
    mine, theirs = _v(c["radiance"]), _v(x["radiance"])
    where = f"{_object_words(ex, r['hit'])} at {_p(point)}"
    head = (
        f"Your shadow ray from {where} towards light {x.get('light')} brings {_p(mine)}; the reference's {_p(theirs)}."
    )
    fa = _f_att(light, point)
    if fa is not None and np.any(theirs > 0):  # a far light's share may be tiny: its ratio is what tells
        from tracer.scene import PointLight, SpotLight  # loaded already: the scene is a model

        f, d = fa
        assert isinstance(light, PointLight | SpotLight), "f_att is a point or a spot light's"
        tiny = 1e-6 * float(theirs.max())
        if _close(mine * f, theirs, rel=0.02, abs_=tiny):
            walk.add("attenuation", f"{head} Yours is the reference's / f_att: the distance attenuation is missing. "
                     f"The light is d = {d:.3g} away: f_att = 1 / (c1 + c2 d + c3 d^2) = {f:.3g} with (c1, c2, c3) = "
                     f"{_p(light.attenuation)}.", c, x)  # fmt: skip
            return
        if _close(mine, theirs * f, rel=0.02, abs_=tiny):
            walk.add("attenuation", f"{head} Yours has the distance attenuation f_att = {f:.3g} (d = {d:.3g}) twice.",
                     c, x)  # fmt: skip
            return
    m = _material(ex, r["hit"])
    what = ""
    if m is not None:
        what = (f" The light's contribution is f_att I cos(theta) (kd / pi + ks (n + 2) / (2 pi) cos^n(alpha)) with "
                f"kd = {_p(m.kd)}, ks = {_p(m.ks)}, n = shininess = {m.shininess:g}; cos(alpha) = R_L . V, the light's "
                "direction mirrored about N against the direction to the eye.")  # fmt: skip
    walk.add("shading", head + what, c, x)


def _terms(walk: _Walk, s: dict, r: dict) -> None:
    ts, tr = s.get("terms") or {}, r.get("terms") or {}
    wrong = [k for k in ("ambient", "diffuse", "specular") if ts.get(k) is not None and not _close(ts[k], tr[k])]
    if not wrong:
        return
    ex = walk.ex
    said = "; ".join(f"{k} {_p(ts[k])} against the reference's {_p(tr[k])}" for k in wrong)
    hints = {
        "ambient": "ambient = ka x the scene's ambient (ka is kd unless set)",
        "diffuse": "diffuse = sum over the lights that reach the point of f_att I cos(theta) kd / pi",
        "specular": "specular = sum of f_att I cos(theta) ks (n + 2) / (2 pi) cos^n(alpha), alpha between the light's "
        "mirror direction R_L and the direction to the eye V",
    }
    walk.add("shading", f"At {_object_words(ex, r['hit'])} at {_p(r['hit']['point'])} your local terms differ: {said}. "
             + "; ".join(hints[k] for k in wrong) + ".", s, r)  # fmt: skip


def _secondary(walk: _Walk, s: dict, r: dict, depth: int) -> None:
    """The reflection and transmission rays of a hit: TIR, the depth limit, weights, and each child whole."""
    ex = walk.ex
    max_depth = ex.scene.render.max_depth
    min_weight = ex.scene.render.min_weight
    mine = {k: [c for c in walk.s_kids[s["id"]] if c["kind"] == k] for k in ("reflection", "transmission")}
    theirs = {k: [c for c in walk.r_kids[r["id"]] if c["kind"] == k] for k in ("reflection", "transmission")}
    where = f"{_object_words(ex, r['hit'])} at {_p(r['hit']['point'])}"
    any_mine = mine["reflection"] or mine["transmission"]
    any_theirs = theirs["reflection"] or theirs["transmission"]
    if any_mine and depth + 1 > max_depth:
        c = (mine["reflection"] + mine["transmission"])[0]
        walk.add("depth", f"Your tracer spawns a {_ray(c)} (depth {depth + 1}) at {where}, past max_depth = "
                 f"{max_depth}: the eye ray has depth 1, and a ray of depth d spawns children only while d + 1 <= "
                 "max_depth.", c, r)  # fmt: skip
        return
    if any_theirs and not any_mine and depth + 1 == max_depth:
        c = (theirs["reflection"] + theirs["transmission"])[0]
        walk.add("depth", f"The reference spawns a {_ray(c)} (depth {depth + 1}) at {where}; yours stops there: "
                 f"max_depth = {max_depth} allows depth {max_depth} (the eye ray: 1).", s, c)  # fmt: skip
        return
    if r.get("end") == "tir" and mine["transmission"]:
        c = mine["transmission"][0]
        walk.add("total_internal_reflection", f"At {where} the ray inside meets the surface beyond the critical "
                 "angle: total internal reflection (sin(theta2) = eta sin(theta1) > 1). There is no transmission ray "
                 "there, and its weight goes to the reflection ray; yours casts one.", c, r)  # fmt: skip
        return
    if r.get("end") == "tir" and mine["reflection"] and theirs["reflection"]:
        a, b = mine["reflection"][0], theirs["reflection"][0]
        if a.get("weight") is not None and not _close(a["weight"], b["weight"]):
            walk.add("total_internal_reflection", f"At {where} there is total internal reflection: no transmission "
                     f"ray, and its weight goes to the reflection ray, whose weight is {_p(b['weight'])}; yours "
                     f"carries {_p(a['weight'])}.", a, b)  # fmt: skip
            return
    if theirs["transmission"] and not mine["transmission"] and mine["reflection"]:
        x = theirs["transmission"][0]
        walk.add("total_internal_reflection", f"At {where} your tracer casts no transmission ray, though the "
                 "reference refracts there: there is no total internal reflection at this angle "
                 "(it happens only leaving the denser side, past the critical angle: eta sin(theta1) > 1, with "
                 "eta = n1 / n2).", s, x)  # fmt: skip
        return
    for kind in ("reflection", "transmission"):
        for i in range(max(len(mine[kind]), len(theirs[kind]))):
            a = mine[kind][i] if i < len(mine[kind]) else None
            b = theirs[kind][i] if i < len(theirs[kind]) else None
            if a is None:
                assert b is not None, "one of the two trees has the ray"
                walk.add("missing_ray", f"The reference casts a {_ray(b)} at {where} (weight {_p(b['weight'])}); "
                         f"yours casts none: a hit spawns a reflection ray when kr > 0 and a transmission ray when "
                         f"kt > 0, while the depth and the weight allow.", s, b)  # fmt: skip
                continue
            if b is None:
                text = f"Your tracer casts a {_ray(a)} at {where}; the reference casts none there"
                if r.get("end") == "min_weight" or (
                    a.get("weight") is not None and max(a["weight"]) < max(min_weight, 1e-30)
                ):
                    text += f": its weight falls below min_weight = {min_weight:g}"
                elif r.get("end") == "absorbed":
                    text += ": kr = kt = 0 there"
                walk.add("extra_ray", text + ".", a, r)
                continue
            # Fresnel's R turns fast at grazing incidence: the weights agree within what the normal's noise makes
            cos_i = abs(float(np.dot(_unit(r["direction"]), _unit(r["hit"]["normal"]))))
            rel = RELATIVE + RAY_ANGLE / max(cos_i, 1e-3)
            if a.get("weight") is not None and not _close(*_ks(s, a, r, b), rel) and _direction_ok(a, b):
                walk.add("fresnel", _weight_words(walk, a, b, r), a, b)
                continue
            _pair(walk, a, b, depth + 1)


def _ks(s: dict, a: dict, r: dict, b: dict) -> tuple[np.ndarray, np.ndarray]:
    """The children's own K's (weight / parent's weight), where both parents' weights are known and not 0, so
    that a difference is found at the ray whose K differs; else their weights (the products from the eye)."""
    ws, wr = s.get("weight"), r.get("weight")
    if ws is None or wr is None or min(ws) <= 0 or min(wr) <= 0:
        return _v(a["weight"]), _v(b["weight"])
    return _v(a["weight"]) / _v(ws), _v(b["weight"]) / _v(wr)


def _direction_ok(a: dict, b: dict) -> bool:
    return _angle(a["direction"], b["direction"]) <= RAY_ANGLE


def _weight_words(walk: _Walk, a: dict, b: dict, r: dict) -> str:
    ex = walk.ex
    m = _material(ex, r["hit"])
    where = f"{_object_words(ex, r['hit'])} at {_p(r['hit']['point'])}"
    text = (f"Your {_ray(a)} from {where} carries weight {_p(a['weight'])}; the reference's {_p(b['weight'])} "
            "(the product of the K's from the eye).")  # fmt: skip
    if m is not None:
        k = "kr" if a["kind"] == "reflection" else "kt"
        text += f" Here {k} = {_p(getattr(m, k))}"
        if m.fresnel:
            share = "R" if a["kind"] == "reflection" else "1 - R"
            text += (f", times the exact dielectric Fresnel {share} (fresnel: true), with R from the angle of "
                     f"incidence and eta (ior = {m.ior:g})")  # fmt: skip
        text += "; the parent's weight multiplies it."
    return text


def _carried(walk: _Walk, s: dict, r: dict) -> None:
    """What a ray carries back, when everything else at it agrees."""
    if s.get("radiance") is None or r.get("radiance") is None or _close(s["radiance"], r["radiance"]):
        return
    ex = walk.ex
    if r.get("hit") is None:
        text = (f"Your {_ray(s)} leaves the scene, as the reference's does, but brings back {_p(s['radiance'])}; the "
                f"background is {_p(ex.scene.background)}.")  # fmt: skip
    else:
        text = (f"Your {_ray(s)} brings back {_p(s['radiance'])} from {_object_words(ex, r['hit'])}; the reference's "
                f"{_p(r['radiance'])}, though the rays below it agree: a ray carries back its local term (ambient + "
                "the lights' sum) plus each child's radiance times the child's K (kr, kt, with Fresnel).")  # fmt: skip
    walk.add("shading", text, s, r)
