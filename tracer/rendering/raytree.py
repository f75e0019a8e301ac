"""One pixel sample's ray tree, traced by the same kernel code as the image.

``trace_one`` runs the integrator's ``trace_sample`` with recording on; this module decodes the
node records into the JSON of docs/scene-format.md ("The ray tree") and fills in what each ray carries
back, bottom-up: a ray returns T (local + sum of K_child L_child) + (1 - T) fog colour, with T
its fog transmittance (1 without fog); a shadow ray returns the light's f_att I cos(theta) f,
or 0 when occluded. The root's radiance is the pixel sample's colour.

Two bounds, each said in the tree: the kernel traces at most `max_tree_rays` eye, reflection and
transmission rays per sample (tracer/limits.py; the image's samples too), and a wanted ray past them ends
its parent with the reason `max_tree_rays`; the record keeps the first `cap` nodes (shadow rays included),
and a larger tree is `truncated`.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from tracer import radiosity
from tracer.integrators import dispatch
from tracer.integrators import record as W
from tracer.kernels.compile import CompiledScene, compile_scene
from tracer.kernels.kinds import End, Integrator, RayKind
from tracer.rendering.progressive import load_kernels, make_record, make_stack
from tracer.scene import Scene, SceneError
from tracer.scene.integrators import INTEGRATORS

DEFAULT_CAP = 8192  # nodes recorded at most; a larger tree is reported as truncated


def _vec(v) -> list[float]:
    return [float(c) for c in v]


def sample_count(scene: Scene) -> int:
    """How many samples a pixel of the scene has, whose ray trees may be asked for: spp, or for the adaptive
    sampler the points of its finest grid, (2^(max_level+1) + 1)^2."""
    if scene.sampler.type == "adaptive":
        return ((1 << (scene.sampler.max_level + 1)) + 1) ** 2
    assert scene.sampler.spp is not None, "the Sampler's validator fills in its type's default spp"
    return scene.sampler.spp


def pixel_sample_errors(x: int, y: int, sample: int, width: int, height: int, samples: int) -> list[dict]:
    """The errors ({path, message}) of a pixel sample (x, y, sample) outside a film of width x height pixels
    with `samples` samples each: POST /api/raytree checks them before it queues anything."""
    errs = []
    for key, v, n, what in (
        ("x", x, width, "column"),
        ("y", y, height, "row"),
        ("sample", sample, samples, "sample index"),
    ):
        if not 0 <= v < n:
            errs.append({"path": key, "message": f"must be a {what} in 0..{n - 1}"})
    return errs


def ray_tree(
    scene: Scene | CompiledScene, x: int, y: int, sample: int = 0, cap: int = DEFAULT_CAP, device: str = "cpu"
) -> dict:
    """The ray tree of sample `sample` of pixel (x, y) (x from the left, y from the top)."""
    cs = scene if isinstance(scene, CompiledScene) else compile_scene(scene, device=device)
    d = cs.data
    errs = pixel_sample_errors(x, y, sample, d.width, d.height, sample_count(cs.scene))
    if errs:
        raise SceneError(errs)
    if INTEGRATORS[d.integrator].prepass == "radiosity" and cs.radiosity is None:
        radiosity.attach(cs, device=device)
    load_kernels(device, [d.integrator])
    rec = make_record(cap, device)
    st = make_stack(1, d.max_depth, device)
    out = wp.zeros(2, dtype=wp.vec3, device=device)
    trace_one = dispatch.KERNELS[Integrator(d.integrator)][2]
    wp.launch(trace_one, dim=1, inputs=[d, x, y, sample, st, rec, out], device=device)
    count = int(rec.count.numpy()[0])
    n = min(count, cap)
    ints, vecs, floats = rec.ints.numpy()[:n], rec.vecs.numpy()[:n], rec.floats.numpy()[:n]
    fog_on = cs.scene.fog.density > 0
    fog_color = np.asarray(cs.scene.fog.color, dtype=np.float64)

    radiance = np.zeros((n, 3))
    kids: list[list[int]] = [[] for _ in range(n)]  # each ray's reflection and transmission children, in order
    for j in range(n):
        parent = int(ints[j, W.I_PARENT])
        if parent >= 0 and ints[j, W.I_KIND] != RayKind.SHADOW:
            kids[parent].append(j)
    for i in range(n - 1, -1, -1):  # children are recorded after their parent
        if ints[i, W.I_KIND] == RayKind.SHADOW:
            radiance[i] = vecs[i, W.V_CARRIED]
            continue
        children = kids[i]
        if ints[i, W.I_HIT] == 0:
            radiance[i] = fog_color if fog_on else np.asarray(cs.scene.background, dtype=np.float64)
            continue
        local = (vecs[i, W.V_EMISSION] + vecs[i, W.V_AMBIENT] + vecs[i, W.V_DIFFUSE] + vecs[i, W.V_SPECULAR]).astype(
            np.float64
        )
        carried = local + sum((vecs[j, W.V_K] * radiance[j] for j in children), np.zeros(3))
        t_fog = float(floats[i, W.F_FOG])
        radiance[i] = t_fog * carried + (1.0 - t_fog) * fog_color if fog_on else carried

    nodes = []
    for i in range(n):
        kind = RayKind(int(ints[i, W.I_KIND]))
        hit = None
        if ints[i, W.I_HIT]:
            obj = int(ints[i, W.I_OBJ])
            light = -1 - obj if obj < 0 else None  # an area light is geometry too
            name = cs.object_names[obj] if light is None else f"light {light} ({cs.scene.lights[light].type})"
            hit = {
                "point": _vec(vecs[i, W.V_POINT]),
                "normal": _vec(vecs[i, W.V_NORMAL]),
                "object": obj if obj >= 0 else None,
                "object_name": name,
                "light": light,
                "material": cs.material_names[int(ints[i, W.I_MAT])],
                "front_face": bool(ints[i, W.I_FRONT]),
            }
        shadow = kind == RayKind.SHADOW
        end = End(int(ints[i, W.I_END]))
        parent = int(ints[i, W.I_PARENT])
        nodes.append(
            {
                "id": i,
                "parent": parent if parent >= 0 else None,
                "kind": kind.name.lower(),
                "depth": int(ints[i, W.I_DEPTH]),
                "origin": _vec(vecs[i, W.V_ORIGIN]),
                "direction": _vec(vecs[i, W.V_DIR]),
                "t": float(floats[i, W.F_T]) if hit else None,
                "hit": hit,
                "weight": _vec(vecs[i, W.V_WEIGHT]),
                "k": _vec(vecs[i, W.V_K]),
                "radiance": _vec(radiance[i]),
                "terms": None
                if shadow or not hit
                else {
                    "ambient": _vec(vecs[i, W.V_AMBIENT]),
                    "diffuse": _vec(vecs[i, W.V_DIFFUSE]),
                    "specular": _vec(vecs[i, W.V_SPECULAR]),
                    "emission": _vec(vecs[i, W.V_EMISSION]),
                },
                "fog_transmittance": float(floats[i, W.F_FOG]) if fog_on and not shadow else None,
                "light": int(ints[i, W.I_LIGHT]) if shadow else None,
                "occluded": bool(ints[i, W.I_OCCLUDED]) if shadow else None,
                "end": None if end == End.NONE else end.name.lower(),
            }
        )
    color, weight = out.numpy()
    return {
        "pixel": [x, y],
        "sample": sample,
        "color": _vec(color),
        "filter_weight": float(weight[0]),
        "time": float(floats[0, W.F_TIME]) if n else None,
        "nodes": nodes,
        "truncated": count > cap,
        "max_tree_rays": int(d.max_tree_rays),
    }


END_WORDS = {  # the same words as the page's (web/js/rays.js)
    "miss": "missed: left the scene (returns the background)",
    "max_depth": "max depth: a reflection or transmission ray was wanted, but depth + 1 > max_depth",
    "min_weight": "min weight: every wanted child's weight fell below min_weight",
    "tir": "total internal reflection: no transmission ray",
    "light": "reached the light",
    "absorbed": "absorbed: kr = kt = 0 here, no reflection or transmission ray",
    "max_tree_rays": "max tree rays: a reflection or transmission ray was wanted, but the sample had traced its "
    "max_tree_rays eye, reflection and transmission rays",
}


def _rgb(v) -> str:
    return "(" + ", ".join(f"{c:.4g}" for c in v) + ")"


def _node_line(n: dict, children: list[dict]) -> str:
    """One ray of a tree in words: kind, hit, weight, what it carries back, why it ended."""
    hit = n["hit"]
    if n["kind"] == "shadow":
        head = f"#{n['id']} shadow ray to light {n['light']}"
        if n["occluded"]:
            where = f"'{hit['object_name']}' at t {n['t']:.4g}" if hit else "something"
            what = f"blocked by {where}"
        else:
            what = "reached the light"
        return f"{head}: {what}; weight {_rgb(n['weight'])}; carries {_rgb(n['radiance'])}"
    head = f"#{n['id']} {n['kind']} ray, depth {n['depth']}"
    if hit:
        what = f"hit '{hit['object_name']}' (material {hit['material']}) at {_rgb(hit['point'])}, t {n['t']:.4g}"
        if not hit["front_face"]:
            what += " from inside"
    else:
        what = "missed: the background"
    if n["end"]:
        ended = f"ended: {END_WORDS.get(n['end'], n['end'])}"
    else:
        kinds = [c["kind"] for c in children if c["kind"] != "shadow"]
        ended = "went on: " + " + ".join(kinds) if kinds else "ended: nothing more to trace"
    if n["end"] == "miss":
        return f"{head}: {what}; weight {_rgb(n['weight'])}; carries {_rgb(n['radiance'])}"
    return f"{head}: {what}; weight {_rgb(n['weight'])}; carries {_rgb(n['radiance'])}; {ended}"


def tree_text(tree: dict) -> str:
    """A ray tree (from `ray_tree`) as indented lines a person reads: one ray per line, each ray's
    children two spaces further in, in the order they were traced."""
    nodes = tree["nodes"]
    children: dict[int | None, list[dict]] = {}
    for n in nodes:
        children.setdefault(n["parent"], []).append(n)
    weight = f", filter weight {tree['filter_weight']:.4g}" if tree["filter_weight"] != 1 else ""
    x, y = tree["pixel"]
    lines = [f"pixel ({x}, {y}), sample {tree['sample']}: colour {_rgb(tree['color'])}{weight}"]
    stack = [(n, 0) for n in reversed(children.get(None, []))]
    while stack:
        n, level = stack.pop()
        kids = children.get(n["id"], [])
        lines.append("  " * level + _node_line(n, kids))
        stack.extend((c, level + 1) for c in reversed(kids))
    if tree["truncated"]:
        lines.append(f"(truncated: only the first {len(nodes)} rays were recorded)")
    if any(n["end"] == "max_tree_rays" for n in nodes):
        lines.append(f"(cut: the sample's tree reached its bound of {tree['max_tree_rays']} rays, max_tree_rays)")
    return "\n".join(lines) + "\n"
