"""Radiosity by progressive refinement with ray-cast form factors (Goral et al. 1984; Cohen et al. 1988).

The diffuse surfaces are cut into patches of about `patch_size` world units: quads, box faces,
planes (clipped to the scene's bounds) and triangles (meshes too). Every surface is two-sided, so
each piece of surface is two patches, one per side, each with its own radiosity. Spheres and disks
are not meshed: they block light but keep none.

Progressive refinement: the patch (or light) with the most unshot power shoots it. The form factors
from the shooter to everything else are estimated by casting rays (Malley's method): `rays` points
uniformly on the shooter, cosine-weighted directions about its normal, each carrying an equal share
of the power to the first surface it meets. A patch that receives power P keeps rho P in its
radiosity and unshot power, and absorbs (1 - rho) P; rays that leave the scene or end on an
unmeshed surface take their power out of the solution ("escaped"). So, exactly at every step:

    emitted = absorbed + unshot + escaped                                  (per RGB channel)

Sources: area lights (power = pi radiance area, shot from points on the light), emissive
materials (a patch's own exitance, pi emission), and point, spot and directional lights, whose
power reaching each patch is computed directly (one shadow ray to the patch centre); for those,
"emitted" counts only the power that reaches a patch.

Units: radiosity B is exitance, W/m^2; the radiance a diffuse patch sends out is B / pi.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from tracer.compile import CompiledScene, RadiosityData, SceneData, box_faces, compile_scene
from tracer.geometry import basis, closest_hit
from tracer.kinds import LIGHT_DISK, LIGHT_QUAD, RAY_OFFSET, T_FAR
from tracer.lights import light_at
from tracer.sampling import concentric_disk, rng_start, sample_cosine_hemisphere, to_world
from tracer.scene import Scene, SceneError

LIGHT_RAYS_PER_PATCH = 256  # an area light shoots at least this many rays per patch side
SNAPSHOT_EVERY_STEP = 16  # snapshots of B after every shot up to this many, then after 32, 64, 128, ...


@dataclass
class Patches:
    """Patch sides as flat arrays (N patches); a parallelogram corner + a e1 + b e2, or a triangle
    corner, corner + e1, corner + e2."""

    corner: np.ndarray  # (N, 3)
    e1: np.ndarray  # (N, 3)
    e2: np.ndarray  # (N, 3)
    triangle: np.ndarray  # (N,) bool
    normal: np.ndarray  # (N, 3) unit normal of the side
    area: np.ndarray  # (N,) world units^2
    reflectance: np.ndarray  # (N, 3) rho: the material's diffuse colour (textures averaged)
    emission: np.ndarray  # (N, 3) emitted exitance, W/m^2 (pi x the material's emission, front side)
    obj: np.ndarray  # (N,) object index
    twin: np.ndarray  # (N,) index of the other side of the same piece of surface

    def __len__(self) -> int:
        return len(self.area)

    def centres(self) -> np.ndarray:
        w = np.where(self.triangle, 1 / 3, 0.5)[:, None]
        return self.corner + w * (self.e1 + self.e2)


@dataclass
class Solution:
    patches: Patches
    radiosity: np.ndarray  # (N, 3) B, W/m^2
    unshot: np.ndarray  # (N, 3) unshot power, W
    emitted: np.ndarray  # (3,) W
    absorbed: np.ndarray  # (3,) W
    escaped: np.ndarray  # (3,) W
    history: list[dict] = field(default_factory=list)  # per step: shooter, unshot total, rays
    direct: np.ndarray | None = None  # (N, 3) B once the lights have shot: emitted + directly lit

    snapshots: dict = field(default_factory=dict)  # step -> (N, 3) B after that many shots (see SNAPSHOT_EVERY_STEP)

    def unshot_total(self) -> float:
        return float(self.unshot.sum())

    def to_json(self) -> dict:
        """The method made visible: the patch mesh (corner, e1, e2, triangle, normal, area, object;
        sides N/2.. are the backs of 0..N/2), the final radiosity, the energy balance, the convergence
        curve (per shot: who shot, how much, the unshot power left), and snapshots of the radiosity
        after every shot up to 16, then 32, 64, ... and the last. Plain lists, ready for JSON."""
        p = self.patches

        def rows(a: np.ndarray, digits: int = 6) -> list:
            return np.round(np.asarray(a, dtype=np.float64), digits).tolist()

        return {
            "patches": {
                "corner": rows(p.corner),
                "e1": rows(p.e1),
                "e2": rows(p.e2),
                "triangle": p.triangle.tolist(),
                "normal": rows(p.normal),
                "area": rows(p.area),
                "object": p.obj.tolist(),
                "reflectance": rows(p.reflectance),
                "emission": rows(p.emission),
            },
            "radiosity": rows(self.radiosity),
            "energy": {
                "emitted": rows(self.emitted),
                "absorbed": rows(self.absorbed),
                "unshot": rows(self.unshot.sum(axis=0)),
                "escaped": rows(self.escaped),
            },
            "history": self.history,
            "snapshots": {str(k): rows(v) for k, v in sorted(self.snapshots.items())},
        }


# ----------------------------------------------------------------------------------------- meshing


def _material_rho(cs: CompiledScene) -> tuple[np.ndarray, np.ndarray]:
    """Per material: diffuse reflectance (textures averaged) and emitted exitance (pi x emission)."""
    mats = cs.data.materials.numpy()
    rho = np.array([m["kd"] for m in mats], dtype=np.float64)
    for i, m in enumerate(mats):
        if m["tex"] == 1:  # checker: half of each colour
            rho[i] = (np.asarray(m["tex_c1"]) + np.asarray(m["tex_c2"])) / 2
        elif m["tex"] == 2:  # image: its mean colour
            off, w, h = cs.data.tex_info.numpy()[m["tex_image"]]
            rho[i] = cs.data.tex_pixels.numpy()[off : off + w * h].mean(axis=0)
    emit = np.array([m["emission"] for m in mats], dtype=np.float64) * math.pi
    return np.clip(rho, 0.0, 1.0), emit


def _scene_bounds(cs: CompiledScene) -> tuple[np.ndarray, np.ndarray]:
    """A box around everything bounded in the scene (and the camera), to clip planes to."""
    pts = [np.asarray(cs.scene.camera.lookfrom, float), np.asarray(cs.scene.camera.lookat, float)]
    for obj in cs.scene.objects:
        for key in ("center", "corner", "min", "max"):
            if hasattr(obj, key):
                pts.append(np.asarray(getattr(obj, key), float))
        if obj.type == "quad":
            pts.append(np.add(obj.corner, np.add(obj.edge1, obj.edge2)))
    for light in cs.scene.lights:
        for key in ("position", "corner", "center"):
            if hasattr(light, key):
                pts.append(np.asarray(getattr(light, key), float))
    if cs.num_triangles:
        pts.extend(cs.data.mesh_points.numpy().astype(float))
    p = np.array(pts)
    lo, hi = p.min(axis=0), p.max(axis=0)
    pad = 0.25 * (hi - lo).max() + 1e-3
    return lo - pad, hi + pad


def build_patches(cs: CompiledScene, patch_size: float) -> Patches:
    """Mesh the scene's quads, boxes, planes and triangles into patches of about patch_size."""
    rho_m, emit_m = _material_rho(cs)
    mat_of = {name: i for i, name in enumerate(cs.material_names)}
    rows: list[tuple] = []  # (corner, e1, e2, triangle, obj, mat)

    def grid(c, e1, e2, obj, mat):
        c, e1, e2 = (np.asarray(v, float) for v in (c, e1, e2))
        nu = max(1, math.ceil(np.linalg.norm(e1) / patch_size))
        nv = max(1, math.ceil(np.linalg.norm(e2) / patch_size))
        for j in range(nv):
            for i in range(nu):
                rows.append((c + e1 * i / nu + e2 * j / nv, e1 / nu, e2 / nv, False, obj, mat))

    def tri(v0, v1, v2, obj, mat):
        v0, v1, v2 = (np.asarray(v, float) for v in (v0, v1, v2))
        longest = max(np.linalg.norm(v1 - v0), np.linalg.norm(v2 - v1), np.linalg.norm(v0 - v2))
        n = max(1, math.ceil(longest / patch_size))
        a, b = (v1 - v0) / n, (v2 - v0) / n
        for j in range(n):
            for i in range(n - j):
                rows.append((v0 + i * a + j * b, a, b, True, obj, mat))
                if i + j < n - 1:  # the upside-down triangle of the cell
                    rows.append((v0 + (i + 1) * a + (j + 1) * b, -b, -a, True, obj, mat))

    lo, hi = _scene_bounds(cs)
    for i, obj in enumerate(cs.scene.objects):
        mat = mat_of[obj.material] if isinstance(obj.material, str) else mat_of[f"objects[{i}].material"]
        if obj.type == "quad":
            grid(obj.corner, obj.edge1, obj.edge2, i, mat)
        elif obj.type == "box":
            for c, e1, e2 in box_faces(obj.min, obj.max, obj.transform):
                grid(c, e1, e2, i, mat)
        elif obj.type == "plane":
            n = np.asarray(obj.normal, float) / np.linalg.norm(obj.normal)
            t, b = _tangents(n)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            rel = corners - np.asarray(obj.point, float)
            u, v = rel @ t, rel @ b
            origin = np.asarray(obj.point, float) + u.min() * t + v.min() * b
            grid(origin, (u.max() - u.min()) * t, (v.max() - v.min()) * b, i, mat)
    if cs.num_triangles:
        pts = cs.data.mesh_points.numpy().astype(float)
        idx = cs.data.mesh_indices.numpy().reshape(-1, 3)
        for f, (i0, i1, i2) in enumerate(idx):
            tri(pts[i0], pts[i1], pts[i2], int(cs.data.face_obj.numpy()[f]), int(cs.data.face_mat.numpy()[f]))
    if not rows:
        raise SceneError(
            [
                {
                    "path": "render.integrator",
                    "message": "the radiosity integrator needs quads, boxes, "
                    "planes or triangles to mesh into patches; this scene has none",
                }
            ]
        )
    corner = np.array([r[0] for r in rows])
    e1 = np.array([r[1] for r in rows])
    e2 = np.array([r[2] for r in rows])
    triangle = np.array([r[3] for r in rows])
    cross = np.cross(e1, e2)
    length = np.linalg.norm(cross, axis=1)
    normal = cross / length[:, None]
    area = np.where(triangle, 0.5, 1.0) * length
    obj = np.array([r[4] for r in rows])
    mat = np.array([r[5] for r in rows])
    n = len(rows)
    # both sides: patch k (front, the normal) and n + k (back); emission on the front side only
    return Patches(
        corner=np.concatenate([corner, corner]),
        e1=np.concatenate([e1, e1]),
        e2=np.concatenate([e2, e2]),
        triangle=np.concatenate([triangle, triangle]),
        normal=np.concatenate([normal, -normal]),
        area=np.concatenate([area, area]),
        reflectance=np.concatenate([rho_m[mat], rho_m[mat]]),
        emission=np.concatenate([emit_m[mat], np.zeros_like(emit_m[mat])]),
        obj=np.concatenate([obj, obj]),
        twin=np.concatenate([np.arange(n) + n, np.arange(n)]),
    )


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(n, a)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t)


# ----------------------------------------------------------------------------------------- kernels


@wp.struct
class PatchMesh:
    mesh: wp.uint64  # every patch side's geometry as triangles (a parallelogram is two)
    tri_front: wp.array(dtype=wp.int32)  # triangle -> front patch index (its back is patch + n)
    n: int  # patches per side


@wp.kernel
def shoot(
    scene: SceneData,
    pm: PatchMesh,
    origin_kind: int,  # 0: a patch (corner, e1, e2, triangle flag), 1: an area light (sampled)
    corner: wp.vec3,
    e1: wp.vec3,
    e2: wp.vec3,
    tri: int,
    light_index: int,
    seed: int,
    step: int,
    n_rays: int,
    power: wp.vec3,
    received: wp.array(dtype=wp.vec3),
):
    """Cast n_rays from the shooter with cosine-weighted directions; add each ray's share of the
    power to the patch side it reaches first (one thread does all rays: the sums are deterministic)."""
    share = power / float(n_rays)
    for r in range(n_rays):
        rng = rng_start(seed, step, r)
        m = int(wp.floor(wp.sqrt(float(n_rays))))
        u1 = wp.randf(rng)
        u2 = wp.randf(rng)
        if r < m * m:  # stratified positions on the shooter
            u1 = (float(r % m) + u1) / float(m)
            u2 = (float(r / m) + u2) / float(m)
        p = wp.vec3(0.0)
        n = wp.vec3(0.0, 1.0, 0.0)
        if origin_kind == 0:
            a = u1
            b = u2
            if tri != 0 and a + b > 1.0:
                a = 1.0 - a
                b = 1.0 - b
            p = corner + a * e1 + b * e2
            n = wp.normalize(wp.cross(e1, e2))
        else:
            light = scene.lights[light_index]
            if light.kind == LIGHT_QUAD:
                p = light.position + u1 * light.edge1 + u2 * light.edge2
                n = light.direction
            elif light.kind == LIGHT_DISK:
                dsk = concentric_disk(u1, u2)
                tu, tv = basis(light.direction)
                p = light.position + light.radius * (dsk[0] * tu + dsk[1] * tv)
                n = light.direction
            else:  # sphere: a uniform point of its surface, shooting outwards
                z = 1.0 - 2.0 * u1
                rr = wp.sqrt(wp.max(0.0, 1.0 - z * z))
                phi = 6.283185307179586 * u2
                n = wp.vec3(rr * wp.cos(phi), rr * wp.sin(phi), z)
                p = light.position + light.radius * n
        d = to_world(sample_cosine_hemisphere(wp.randf(rng), wp.randf(rng)), n)
        o = p + RAY_OFFSET * n
        h = closest_hit(scene, o, d, T_FAR, 0.0)
        q = wp.mesh_query_ray(pm.mesh, o, d, T_FAR)
        if q.result and (h.hit == 0 or q.t <= h.t * (1.0 + 1.0e-4) + 1.0e-5):
            k = pm.tri_front[q.face]
            if wp.dot(d, q.normal) > 0.0:  # the ray meets the back side
                k = k + pm.n
            received[k] = received[k] + share


@wp.kernel
def direct(
    scene: SceneData,
    centres: wp.array(dtype=wp.vec3),
    normals: wp.array(dtype=wp.vec3),
    light_index: int,
    received: wp.array(dtype=wp.vec3),
):
    """Irradiance of a point, spot or directional light at each patch centre (one shadow ray)."""
    i = wp.tid()
    light = scene.lights[light_index]
    p = centres[i]
    n = normals[i]
    l, dist, e, reaches = light_at(light, p)
    cos = wp.dot(n, l)
    if reaches != 0 and cos > 0.0:
        o = p + RAY_OFFSET * n
        h = closest_hit(scene, o, l, dist, 0.0)
        if h.hit == 0:
            received[i] = e * cos  # W/m^2; times the area outside


# ----------------------------------------------------------------------------------------- solver


def _patch_mesh(p: Patches) -> tuple[PatchMesh, list]:
    n = len(p) // 2
    pts, tri_front = [], []
    for k in range(n):
        c, a, b = p.corner[k], p.e1[k], p.e2[k]
        if p.triangle[k]:
            pts += [c, c + a, c + b]
            tri_front.append(k)
        else:
            pts += [c, c + a, c + a + b, c, c + a + b, c + b]
            tri_front += [k, k]
    points = wp.array(np.array(pts, dtype=np.float32), dtype=wp.vec3)
    indices = wp.array(np.arange(len(pts), dtype=np.int32), dtype=wp.int32)
    mesh = wp.Mesh(points=points, indices=indices)
    pm = PatchMesh()
    pm.mesh, pm.n = mesh.id, n
    pm.tri_front = wp.array(np.array(tri_front, dtype=np.int32), dtype=wp.int32)
    return pm, [mesh, points, indices]


def solve(
    scene: Scene | CompiledScene,
    patch_size: float = 0.25,
    rays: int = 4096,
    threshold: float = 0.01,
    max_steps: int = 2000,
    seed: int = 0,
    on_step=None,
) -> Solution:
    """Progressive refinement until the unshot power is below `threshold` of the emitted power (or
    `max_steps` shots). `on_step(solution, step)` is called after each shot."""
    cs = scene if isinstance(scene, CompiledScene) else compile_scene(scene)
    p = build_patches(cs, patch_size)
    pm, keep = _patch_mesh(p)
    n = len(p)
    B = p.emission.copy()  # exitance: emitted, then + reflected
    unshot = p.emission * p.area[:, None]
    emitted = unshot.sum(axis=0)
    absorbed = np.zeros(3)
    escaped = np.zeros(3)
    sol = Solution(p, B, unshot, emitted, absorbed, escaped)
    received = wp.zeros(n, dtype=wp.vec3)

    def receive(power_in: np.ndarray) -> None:
        kept = p.reflectance * power_in
        sol.radiosity += kept / p.area[:, None]
        sol.unshot += kept
        sol.absorbed += (power_in - kept).sum(axis=0)

    step = 0
    # 1. point, spot and directional lights: their power reaching each patch, directly
    centres = wp.array(p.centres().astype(np.float32), dtype=wp.vec3)
    normals = wp.array(p.normal.astype(np.float32), dtype=wp.vec3)
    for li, light in enumerate(cs.scene.lights):
        if light.type in ("point", "spot", "directional"):
            received.zero_()
            wp.launch(direct, dim=n, inputs=[cs.data, centres, normals, li, received])
            power_in = received.numpy().astype(np.float64) * p.area[:, None]
            sol.emitted += power_in.sum(axis=0)
            receive(power_in)
            sol.history.append({"step": step, "shooter": f"lights[{li}]", "unshot": sol.unshot_total()})
            step += 1
    # 2. area lights: shoot their whole power (pi L A)
    for li, light in enumerate(cs.scene.lights):
        if light.type in ("quad", "disk", "sphere"):
            area = float(cs.data.lights.numpy()[li]["area"])
            power = np.asarray(light.radiance, float) * math.pi * area
            sol.emitted += power
            # the lights' shots make the directly lit part: enough rays for every patch to get its share
            light_rays = max(rays, LIGHT_RAYS_PER_PATCH * n)
            _shoot(sol, cs, pm, received, 1, None, li, seed, step, light_rays, power, receive)
            sol.history.append({"step": step, "shooter": f"lights[{li}]", "unshot": sol.unshot_total()})
            if on_step:
                on_step(sol, step)
            step += 1
    sol.direct = sol.radiosity.copy()
    # 3. progressive refinement: the patch with the most unshot power shoots it
    sol.snapshots[step] = sol.radiosity.copy()
    while step < max_steps and sol.unshot_total() > threshold * float(sol.emitted.sum()):
        k = int(np.argmax(sol.unshot.sum(axis=1)))
        power = sol.unshot[k].copy()
        sol.unshot[k] = 0.0
        _shoot(sol, cs, pm, received, 0, k, -1, seed, step, rays, power, receive)
        sol.history.append({"step": step, "shooter": k, "power": float(power.sum()), "unshot": sol.unshot_total()})
        if on_step:
            on_step(sol, step)
        step += 1
        if step <= SNAPSHOT_EVERY_STEP or step & (step - 1) == 0:  # every early shot, then 32, 64, ...
            sol.snapshots[step] = sol.radiosity.copy()
    sol.snapshots[step] = sol.radiosity.copy()  # and the final solution
    del keep
    return sol


def _shoot(sol, cs, pm, received, kind, k, li, seed, step, rays, power, receive) -> None:
    p = sol.patches
    received.zero_()
    if kind == 0:
        args = [wp.vec3(*p.corner[k]), wp.vec3(*p.e1[k]), wp.vec3(*p.e2[k]), int(p.triangle[k])]
        if k >= len(p) // 2:  # a back side shoots from the other face: flip its edges
            args = [wp.vec3(*p.corner[k]), wp.vec3(*p.e2[k]), wp.vec3(*p.e1[k]), int(p.triangle[k])]
    else:
        args = [wp.vec3(0.0), wp.vec3(0.0), wp.vec3(0.0), 0]
    wp.launch(
        shoot,
        dim=1,
        inputs=[cs.data, pm, kind, *args, li, seed, step, rays, wp.vec3(*power), received],
    )
    power_in = received.numpy().astype(np.float64)
    sol.escaped += power - power_in.sum(axis=0)
    receive(power_in)


# ----------------------------------------------------------------------------------------- display


def corner_values(p: Patches, values: np.ndarray) -> np.ndarray:
    """Per patch side, the values at its triangle corners (2 triangles for a parallelogram), each the
    mean of the values of the same object's patches facing the same way that share that corner (smooth
    shading of a piecewise-constant solution). Returns (sides, 6, 3): corners of up to 2 triangles."""
    n2 = len(p)
    quads = ~p.triangle
    # corners of each patch's triangles, in the order _patch_mesh emits them
    c, a, b = p.corner, p.e1, p.e2
    tri_pts = np.where(
        quads[:, None, None],
        np.stack([c, c + a, c + a + b, c, c + a + b, c + b], axis=1),
        np.stack([c, c + a, c + b, c, c, c], axis=1),
    )
    # corners are shared by patches of one object, one side and one orientation (no smoothing over creases)
    side = [tuple(v) for v in np.round(p.normal * 1e3).astype(np.int64)]
    key_pts = np.round(tri_pts / 1e-6).astype(np.int64)
    sums: dict = {}
    for k in range(n2):
        for j in range(6 if quads[k] else 3):
            key = (int(p.obj[k]), side[k], *key_pts[k, j])
            acc = sums.setdefault(key, [np.zeros(3), 0])
            acc[0] += values[k]
            acc[1] += 1
    out = np.zeros((n2, 6, 3))
    for k in range(n2):
        for j in range(6 if quads[k] else 3):
            total, count = sums[(int(p.obj[k]), side[k], *key_pts[k, j])]
            out[k, j] = total / count
    return out


def attach(cs: CompiledScene, device: str = "cpu") -> Solution:
    """Solve the scene's radiosity (render.radiosity settings) and put it in cs.data.rad for the
    kernels; the Solution stays in cs.radiosity (the patches, the convergence curve)."""
    cfg = cs.scene.render.radiosity
    sol = solve(
        cs,
        patch_size=cfg.patch_size,
        rays=cfg.rays,
        threshold=cfg.threshold,
        max_steps=cfg.max_steps,
        seed=cs.scene.render.seed,
    )
    p = sol.patches
    pm, keep = _patch_mesh(p)
    n = len(p) // 2
    indirect = np.maximum(sol.radiosity - sol.direct, 0.0)
    r = RadiosityData()
    r.corners = _triangle_corners(pm, p, corner_values(p, sol.radiosity), device)
    r.corners_ind = _triangle_corners(pm, p, corner_values(p, indirect), device)
    r.active = 1
    r.mode = {"two-pass": 0, "flat": 1, "smooth": 2}[cfg.display]
    r.mesh, r.tri_patch, r.n = pm.mesh, pm.tri_front, n
    r.tri_obj = wp.array(p.obj[pm.tri_front.numpy()].astype(np.int32), dtype=wp.int32, device=device)
    r.radiosity = wp.array(sol.radiosity.astype(np.float32), dtype=wp.vec3, device=device)
    r.indirect = wp.array(indirect.astype(np.float32), dtype=wp.vec3, device=device)
    r.rho = wp.array(p.reflectance.astype(np.float32), dtype=wp.vec3, device=device)
    r.max_dist = float(1e-3 * max(1.0, cfg.patch_size))
    cs.data.rad = r
    cs.keep += keep
    cs.radiosity = sol
    return sol


def _triangle_corners(pm: PatchMesh, p: Patches, corners: np.ndarray, device: str):
    """(2 x 3 per triangle of the patch mesh) corner values: every front triangle, then every back one."""
    n = len(p) // 2
    tri_patch = pm.tri_front.numpy()
    out = []
    for offset in (0, n):
        seen: dict = {}
        for k in tri_patch:
            first = seen.get(int(k), 0)  # a parallelogram's first or second triangle
            out.append(corners[k + offset, 3 * first : 3 * first + 3])
            seen[int(k)] = first + 1
    return wp.array(np.concatenate(out).astype(np.float32), dtype=wp.vec3, device=device)
