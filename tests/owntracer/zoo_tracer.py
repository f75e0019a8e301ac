"""A student's own Whitted ray tracer, in plain Python: the example of the bug zoo (issue #38).

It follows the scene format's "Precise semantics" (docs/scene-format.md) the way a careful student would:
spheres, planes and quads; point lights with distance attenuation f_att = 1 / (c1 + c2 d + c3 d^2); Phong
as the normalised BRDF f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha), cos(theta) multiplying both; the
ambient term ka Ia; shadow rays; reflection (kr) and transmission (kt) rays with exact Fresnel and total
internal reflection, up to `max_depth` bounces while the weight stays >= `min_weight`; one ray through
each pixel's centre. Every ray is logged with docs/own-tracer/treelog.py, as a student's tree log.

Each switch of BUGS puts in one classic mistake of the lecture, and names the `what` the service's
feedback should give for it. `bug_pixels` finds where a bug changes the output on a scene.

Vectors are tuples of floats and the code is scalar on purpose: it reads like the lecture's pseudocode,
and a 64x48 image of the zoo scene takes about a second.
"""

from __future__ import annotations

import importlib.util
import io
import json
import math
from functools import cache
from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent
ZOO_SCENE = HERE / "zoo_scene.json"
_LOGGER = HERE.parents[1] / "docs" / "own-tracer" / "treelog.py"
_spec = importlib.util.spec_from_file_location("zoo_treelog", _LOGGER)
treelog = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(treelog)

OFFSET = 1e-4  # spawned rays start at hit + 1e-4 N, N turned to the side the new ray travels into
T_FAR = 1e30

BUGS = {  # switch -> the `what` the feedback should name first
    "shadow_acne": "shadow_acne",  # shadow rays start at the hit point itself (float32 hit, plain t > 0)
    "flipped_normal": "normal",  # the normal is never turned to face the ray (wrong inside the glass)
    "reflection_sign": "reflection_direction",  # R = D + 2 (N.D) N
    "ior_inverted": "refraction_direction",  # Snell's law with n2 / n1
    "no_tir": "total_internal_reflection",  # sqrt(|1 - sin^2|): never a total internal reflection
    "fresnel_weights": "fresnel",  # R and 1 - R swapped between reflection and transmission
    "no_attenuation": "attenuation",  # f_att = 1: no fall-off with distance
    "specular_vector": "shading",  # cos(alpha) from the half vector, N.H (Blinn), not R_L.V
    "half_pixel": "eye_ray",  # the eye ray through the pixel's corner (x + 0, y + 0)
    "vfov_horizontal": "eye_ray",  # vfov taken as the horizontal field of view
    "depth_off_by_one": "depth",  # the eye ray counted as depth 0: one generation too many
    "no_srgb": "encoding",  # the PNG holds linear values: the trees are right, the picture is not
}


# --------------------------------------------------------------------------- vectors (tuples of 3 floats)


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def mul(a, b):
    """Component-wise product (colours)."""
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    return scale(a, 1.0 / math.sqrt(dot(a, a)))


def rgb(x):
    """A colour from the scene: a number means grey."""
    return (float(x),) * 3 if isinstance(x, (int, float)) else tuple(float(c) for c in x)


BLACK = (0.0, 0.0, 0.0)


# --------------------------------------------------------------------------- the scene


class Material:
    def __init__(self, m: dict):
        self.kd = rgb(m.get("kd", 0.5))  # diffuse reflectance
        self.ka = rgb(m["ka"]) if m.get("ka") is not None else self.kd  # ambient coefficient
        self.ks = rgb(m.get("ks", 0.0))  # specular coefficient
        self.shininess = float(m.get("shininess", 32.0))  # Phong exponent n
        self.kr = rgb(m.get("kr", 0.0))  # weight of the reflection ray
        self.kt = rgb(m.get("kt", 0.0))  # weight of the transmission ray
        self.ior = float(m.get("ior", 1.5))  # index of refraction inside (outside is 1)
        self.fresnel = bool(m.get("fresnel", False))  # scale kr, kt by R, 1 - R


class Shape:
    """A sphere, plane or quad, with its material."""

    def __init__(self, o: dict, material: Material):
        self.type = o["type"]
        self.material = material
        if self.type == "sphere":
            self.center, self.radius = tuple(o["center"]), float(o["radius"])
        elif self.type == "plane":
            self.point, self.normal = tuple(o["point"]), normalize(tuple(o["normal"]))
        elif self.type == "quad":
            self.corner, self.e1, self.e2 = tuple(o["corner"]), tuple(o["edge1"]), tuple(o["edge2"])
            m = cross(self.e1, self.e2)
            self.normal = normalize(m)
            mm = dot(m, m)  # p = corner + a e1 + b e2: a = wa.(p - corner), b = wb.(p - corner)
            self.wa, self.wb = scale(cross(self.e2, m), 1 / mm), scale(cross(m, self.e1), 1 / mm)
        else:
            raise ValueError(f"this tracer knows spheres, planes and quads, not {self.type}")

    def intersect(self, o, d, t_max):
        """The nearest t in (0, t_max) where o + t d (d unit) meets the surface, or None."""
        if self.type == "sphere":
            oc = sub(o, self.center)
            b = dot(oc, d)
            disc = b * b - (dot(oc, oc) - self.radius * self.radius)
            if disc < 0:
                return None
            t = -b - math.sqrt(disc)
            if t <= 0:
                t = -b + math.sqrt(disc)
        else:
            p0 = self.point if self.type == "plane" else self.corner
            denom = dot(d, self.normal)
            if abs(denom) < 1e-12:
                return None
            t = dot(sub(p0, o), self.normal) / denom
            if self.type == "quad" and 0 < t < t_max:
                q = sub(add(o, scale(d, t)), self.corner)
                if not (0 <= dot(self.wa, q) <= 1 and 0 <= dot(self.wb, q) <= 1):
                    return None
        return t if 0 < t < t_max else None

    def normal_at(self, p):
        """The geometric normal: outwards for a sphere, the given one for a plane, e1 x e2 for a quad."""
        if self.type == "sphere":
            return normalize(sub(p, self.center))
        return self.normal


class Scene:
    def __init__(self, data: dict):
        cam = data["camera"]
        self.width, self.height = int(data["film"]["width"]), int(data["film"]["height"])
        self.exposure = float(data["film"].get("exposure", 0.0))
        self.eye = tuple(cam["lookfrom"])
        self.forward = normalize(sub(tuple(cam["lookat"]), self.eye))
        self.right = normalize(cross(self.forward, tuple(cam.get("vup", (0, 1, 0)))))
        self.up = cross(self.right, self.forward)
        self.vfov = float(cam.get("vfov", 40.0))  # FULL vertical field of view, degrees
        render = data.get("render", {})
        self.max_depth = int(render.get("max_depth", 5))
        self.min_weight = float(render.get("min_weight", 0.001))
        self.background = rgb(data.get("background", 0.0))
        self.ambient = rgb(data.get("ambient", 0.0))
        named = {name: Material(m) for name, m in data.get("materials", {}).items()}
        self.shapes = [
            Shape(o, named[o["material"]] if isinstance(o["material"], str) else Material(o["material"]))
            for o in data["objects"]
        ]
        self.lights = []  # (position, intensity, attenuation)
        for light in data.get("lights", []):
            if light["type"] != "point":
                raise ValueError(f"this tracer knows point lights, not {light['type']}")
            attenuation = tuple(light.get("attenuation", (0.0, 0.0, 1.0)))
            self.lights.append((tuple(light["position"]), rgb(light["intensity"]), attenuation))

    def closest_hit(self, o, d, t_max=T_FAR):
        """(t, object index) of the nearest surface along the ray, or None."""
        best = None
        for i, shape in enumerate(self.shapes):
            t = shape.intersect(o, d, t_max)
            if t is not None:
                best, t_max = (t, i), t
        return best


# --------------------------------------------------------------------------- optics


def reflect(d, n, bugs=()):
    """The mirror direction of d about the unit normal n."""
    if "reflection_sign" in bugs:
        return add(d, scale(n, 2 * dot(d, n)))  # BUG: the sign of the normal's part
    return sub(d, scale(n, 2 * dot(d, n)))


def cos_transmitted(sin2_t, bugs=()):
    """cos of the refracted angle, or None under total internal reflection (sin^2 >= 1)."""
    if "no_tir" in bugs:
        return math.sqrt(abs(1 - sin2_t))  # BUG: never a total internal reflection
    return None if sin2_t >= 1 else math.sqrt(1 - sin2_t)


def refract(d, n, eta, bugs=()):
    """Snell's law: d and n unit, n facing d, eta = n_incident / n_transmitted. None under TIR."""
    cos_i = min(-dot(d, n), 1.0)
    cos_t = cos_transmitted(eta * eta * (1 - cos_i * cos_i), bugs)
    if cos_t is None:
        return None
    return normalize(add(scale(d, eta), scale(n, eta * cos_i - cos_t)))


def fresnel(cos_i, eta, bugs=()):
    """Exact unpolarised dielectric reflectance R = (rs^2 + rp^2) / 2; 1 under total internal reflection."""
    ci = min(max(cos_i, 0.0), 1.0)
    ct = cos_transmitted(eta * eta * (1 - ci * ci), bugs)
    if ct is None:
        return 1.0
    rs = (eta * ci - ct) / (eta * ci + ct)
    rp = (ci - eta * ct) / (ci + eta * ct)
    return 0.5 * (rs * rs + rp * rp)


def scatter_weights(m: Material, d, n, front, bugs=()):
    """(kr, kt, refracted direction or None, tir): the weights of the reflection and transmission rays."""
    eta = 1 / m.ior if front else m.ior  # n_incident / n_transmitted
    eta_snell = 1 / eta if "ior_inverted" in bugs else eta  # BUG: n2 / n1
    kr, kt, tdir, tir = m.kr, m.kt, None, False
    if max(kt) > 0:
        tdir = refract(d, n, eta_snell, bugs)
        tir = tdir is None
    if m.fresnel:
        r = 1.0 if tir else fresnel(-dot(d, n), eta, bugs)
        if "fresnel_weights" in bugs:
            r = 1 - r  # BUG: R and 1 - R swapped
        kr, kt = scale(kr, r), scale(kt, 1 - r)
    if tir:  # all goes to the reflection ray
        kr, kt = (kr if m.fresnel else add(kr, kt)), BLACK
    return kr, kt, tdir, tir


def phong(m: Material, n, l, v, bugs=()):
    """(diffuse, specular) of the BRDF times cos(theta), per unit of the light's E = f_att I."""
    cos_theta = max(dot(n, l), 0.0)
    if "specular_vector" in bugs:
        cos_alpha = max(dot(n, normalize(add(l, v))), 0.0)  # BUG: Blinn's N.H, not R_L.V
    else:
        r_l = sub(scale(n, 2 * dot(n, l)), l)  # the light's direction mirrored about n
        cos_alpha = max(dot(r_l, v), 0.0)
    spec = 0.0
    if cos_alpha > 0 and max(m.ks) > 0:
        spec = (m.shininess + 2) / (2 * math.pi) * cos_alpha**m.shininess * cos_theta
    return scale(m.kd, cos_theta / math.pi), scale(m.ks, spec)


def offset(p, n, d):
    """hit + 1e-4 N, with N turned to the side the new ray d travels into."""
    return add(p, scale(n, -OFFSET if dot(n, d) < 0 else OFFSET))


# --------------------------------------------------------------------------- tracing


def eye_ray(scene: Scene, x: int, y: int, bugs=()):
    """The ray from the eye through the centre of pixel (x, y)."""
    u = 0.0 if "half_pixel" in bugs else 0.5  # BUG: x + 0, the pixel's corner
    h = math.tan(math.radians(scene.vfov) / 2)
    aspect = scene.width / scene.height
    sx = (2 * (x + u) / scene.width - 1) * h * aspect
    sy = (1 - 2 * (y + u) / scene.height) * h
    if "vfov_horizontal" in bugs:
        sx, sy = sx / aspect, sy / aspect  # BUG: vfov as the horizontal angle
    return scene.eye, normalize(add(scene.forward, add(scale(scene.right, sx), scale(scene.up, sy))))


def float32_point(o, d, t):
    """o + t d in float32 arithmetic, as a tracer written with float32 vectors computes it."""
    o32, d32 = np.asarray(o, np.float32), np.asarray(d, np.float32)
    return tuple(float(c) for c in o32 + np.float32(t) * d32)


def direct_light(scene: Scene, tree, node, p, n, v, m: Material, weight, bugs=()):
    """Diffuse and specular light at p from every point light, one shadow ray each (logged)."""
    diffuse, specular = BLACK, BLACK
    for index, (position, intensity, (c1, c2, c3)) in enumerate(scene.lights):
        to_light = sub(position, p)
        dist = math.sqrt(dot(to_light, to_light))
        l = scale(to_light, 1 / dist)
        if dot(n, l) <= 0:  # the light is behind the surface: no shadow ray
            continue
        f_att = 1.0 if "no_attenuation" in bugs else 1 / (c1 + c2 * dist + c3 * dist * dist)  # BUG: 1
        e = scale(intensity, f_att)
        origin = p if "shadow_acne" in bugs else offset(p, n, l)  # BUG: no offset
        blocker = scene.closest_hit(origin, l, dist)
        d_term, s_term = phong(m, n, l, v, bugs)
        carried = BLACK if blocker else mul(e, add(d_term, s_term))
        if blocker:
            t, obj = blocker
            q = add(origin, scale(l, t))
            ng = scene.shapes[obj].normal_at(q)
            hit = (q, ng if dot(ng, l) < 0 else scale(ng, -1), obj)
            tree.shadow(node, origin, l, index, True, t=t, hit=hit, radiance=BLACK, weight=weight)
        else:
            tree.shadow(node, origin, l, index, False, radiance=carried, weight=weight)
            diffuse, specular = add(diffuse, mul(e, d_term)), add(specular, mul(e, s_term))
    return diffuse, specular


def trace(scene: Scene, tree, kind, parent, o, d, weight, depth, bugs=()):
    """The radiance the ray (o, d) of `kind` carries back; logs it and its subtree as nodes of `tree`.
    `weight` is the product of the K's from the eye down to this ray, `depth` 1 for the eye ray."""
    node = tree.add(kind, parent, o, d, weight)
    found = scene.closest_hit(o, d)
    if found is None:  # the ray leaves the scene
        tree.miss(node)
        tree.set(node, radiance=scene.background)
        return scene.background
    t, obj = found
    shape = scene.shapes[obj]
    m = shape.material
    p = add(o, scale(d, t))
    if "shadow_acne" in bugs:  # BUG (with the missing offset): the hit point computed in float32
        p = float32_point(o, d, t)
    ng = shape.normal_at(p)
    front = dot(d, ng) < 0  # did the ray arrive on the side the normal points to?
    n = ng if front or "flipped_normal" in bugs else scale(ng, -1)  # BUG: not turned towards the ray
    tree.hit(node, t, p, n, obj)

    # the local term: ka Ia + the point lights' direct light
    ambient = mul(m.ka, scene.ambient)
    diffuse, specular = direct_light(scene, tree, node, p, n, scale(d, -1), m, weight, bugs)
    radiance = add(ambient, add(diffuse, specular))

    # secondary rays, each of depth + 1, while depth + 1 <= max_depth and the weight >= min_weight
    last = scene.max_depth + 1 if "depth_off_by_one" in bugs else scene.max_depth  # BUG: one too many
    if (max(m.kr) > 0 or max(m.kt) > 0) and depth + 1 <= last:
        kr, kt, tdir, _tir = scatter_weights(m, d, n, front, bugs)
        rdir = normalize(reflect(d, n, bugs))
        for child, k, direction in (("reflection", kr, rdir), ("transmission", kt, tdir)):
            w = mul(weight, k)
            if max(w) <= 0 or max(w) < scene.min_weight:  # also no transmission ray under TIR (kt = 0)
                continue
            origin = offset(p, ng, direction)
            carried = trace(scene, tree, child, node, origin, direction, w, depth + 1, bugs)
            radiance = add(radiance, mul(k, carried))
    tree.set(node, radiance=radiance, terms={"ambient": ambient, "diffuse": diffuse, "specular": specular})
    return radiance


def pixel_tree(scene: Scene, x: int, y: int, bugs=()):
    """The tree of the ray through pixel (x, y), as a treelog.PixelTree whose `color` is the pixel's."""
    tree = treelog.PixelTree(x, y)
    o, d = eye_ray(scene, x, y, bugs)
    tree.color = trace(scene, tree, "eye", None, o, d, (1.0, 1.0, 1.0), 1, bugs)
    return tree


# --------------------------------------------------------------------------- output


def render(scene_dict: dict, bugs=()):
    """(image, trees): the linear (H, W, 3) float image and every pixel's tree dict, keyed (x, y)."""
    scene = Scene(scene_dict)
    image = np.zeros((scene.height, scene.width, 3))
    trees = {}
    for y in range(scene.height):
        for x in range(scene.width):
            tree = pixel_tree(scene, x, y, bugs)
            image[y, x] = tree.color
            trees[x, y] = tree.as_dict()
    return image, trees


def tree_log(scene_dict: dict, pixels, bugs=()) -> dict:
    """The tree log {"trees": [...]} of the given pixels, as the service takes it."""
    scene = Scene(scene_dict)
    log = treelog.TreeLog()
    for x, y in pixels:
        log.trees.append(pixel_tree(scene, x, y, bugs))
    return log.as_dict()


def srgb8(image: np.ndarray, exposure: float = 0.0, bugs=()) -> np.ndarray:
    """The 8-bit picture: 2^exposure L, clamped to [0, 1], through the sRGB OETF."""
    x = np.clip(image * 2.0**exposure, 0.0, 1.0)
    if "no_srgb" not in bugs:  # BUG: the linear values themselves
        x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(x * 255).astype(np.uint8)


def png_bytes(image: np.ndarray, exposure: float = 0.0, bugs=()) -> bytes:
    out = io.BytesIO()
    Image.fromarray(srgb8(image, exposure, bugs), "RGB").save(out, format="PNG")
    return out.getvalue()


# --------------------------------------------------------------------------- the zoo


def zoo_scene() -> dict:
    return json.loads(ZOO_SCENE.read_text())


@cache
def zoo_render(bug: str | None = None):
    """(linear image, trees by pixel, 8-bit picture) of the zoo scene with one bug (None: correct)."""
    bugs = () if bug is None else (bug,)
    data = zoo_scene()
    image, trees = render(data, bugs)
    return image, trees, srgb8(image, data["film"].get("exposure", 0.0), bugs)


def bug_pixels(bug: str) -> list[tuple[int, int]]:
    """The pixels (x, y) of the zoo scene where `bug` shows: its tree or its 8-bit pixel differs from the
    correct tracer's (zoo_trees.tree_difference, with the tolerances stated there), in raster order."""
    from tests.owntracer.zoo_trees import tree_difference

    if bug not in BUGS:
        raise ValueError(f"no bug {bug!r}: {', '.join(BUGS)}")
    _, good_trees, good_png = zoo_render(None)
    _, bad_trees, bad_png = zoo_render(bug)
    return [
        (x, y)
        for (x, y), tree in good_trees.items()
        if tree_difference(tree, bad_trees[x, y]) is not None or (good_png[y, x] != bad_png[y, x]).any()
    ]
