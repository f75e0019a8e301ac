"""The radiosity patches: every surface the solve sees, cut into patches of about `patch_size` world units.

Quads, box faces, planes (clipped to the scene's bounds), triangles and meshes are cut into
parallelograms and triangles; spheres into a latitude-longitude net of triangles inscribed in them;
disks into rings of triangles. Every surface is two-sided, so each piece of surface is two patches,
one per side, each with its own radiosity. A patch of a sphere or a disk stands for the piece of the
curved surface it covers: its area is that piece's area (a spherical triangle's area is r^2 times its
solid angle), and it shoots from points of the true surface, so nothing is lost to the facets.

How many patches a scene makes is counted before any meshing, in tracer/meshing.py (the limits);
`patch_index` puts the patches in one wp.Mesh, for `lookup.patch_at`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from tracer import meshing
from tracer.kernels.compile import CompiledScene
from tracer.kernels.kinds import PatchKind, Texture
from tracer.kernels.structs import PatchIndex
from tracer.scene import SceneError

SPHERE_MIN_SEGMENTS = meshing.SPHERE_MIN_SEGMENTS  # a sphere's net: at least this many triangles around, and rows
DISK_MIN_SECTORS = meshing.DISK_MIN_SECTORS  # a disk's rings have at least this many sectors


@dataclass
class Patches:
    """Patch sides as flat arrays (N patches); a parallelogram corner + a e1 + b e2, or a triangle
    corner, corner + e1, corner + e2. The first N/2 are the fronts (the side of e1 x e2), the rest
    their backs. Per scene object, how its points find their patches (`patch_at`)."""

    corner: np.ndarray  # (N, 3)
    e1: np.ndarray  # (N, 3)
    e2: np.ndarray  # (N, 3)
    triangle: np.ndarray  # (N,) bool
    normal: np.ndarray  # (N, 3) unit normal of the side (of the flat facet)
    area: np.ndarray  # (N,) world units^2 of the surface the patch stands for
    reflectance: np.ndarray  # (N, 3) rho: the material's diffuse colour (textures averaged)
    emission: np.ndarray  # (N, 3) emitted exitance, W/m^2 (pi x the material's emission, front side)
    obj: np.ndarray  # (N,) object index
    twin: np.ndarray  # (N,) index of the other side of the same piece of surface
    sphere_center: np.ndarray  # (N, 3) a sphere patch's sphere centre (time 0)
    sphere_radius: np.ndarray  # (N,) its radius; 0 for a flat patch
    object_kind: np.ndarray  # (objects,) PatchKind
    object_center: np.ndarray  # (objects, 3) a sphere's or a disk's centre
    object_radius: np.ndarray  # (objects,) a sphere's radius; a disk's inscribed radius of its facets

    def __len__(self) -> int:
        return len(self.area)

    def centres(self) -> np.ndarray:
        """The centre of each flat facet."""
        w = np.where(self.triangle, 1 / 3, 0.5)[:, None]
        return self.corner + w * (self.e1 + self.e2)

    def surface_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Each patch side's centre on the true surface (a sphere's facet centre projected onto the
        sphere) and the unit normal of the side there."""
        c, n = self.centres(), self.normal.copy()
        on_sphere = self.sphere_radius > 0
        if on_sphere.any():
            radial = c[on_sphere] - self.sphere_center[on_sphere]
            radial /= np.linalg.norm(radial, axis=1, keepdims=True)
            c[on_sphere] = self.sphere_center[on_sphere] + self.sphere_radius[on_sphere, None] * radial
            n[on_sphere] = radial * np.sign(np.sum(radial * self.normal[on_sphere], axis=1))[:, None]
        return c, n


def _material_rho(cs: CompiledScene) -> tuple[np.ndarray, np.ndarray]:
    """Per material: diffuse reflectance (textures averaged) and emitted exitance (pi x emission)."""
    mats = cs.data.materials.numpy()
    rho = np.array([m["kd"] for m in mats], dtype=np.float64)
    for i, m in enumerate(mats):
        if m["tex"] == Texture.CHECKER:  # half of each colour
            rho[i] = (np.asarray(m["tex_c1"]) + np.asarray(m["tex_c2"])) / 2
        elif m["tex"] == Texture.IMAGE:  # its mean colour
            off, w, h = cs.data.tex_info.numpy()[m["tex_image"]]
            rho[i] = cs.data.tex_pixels.numpy()[off : off + w * h].mean(axis=0)
    emit = np.array([m["emission"] for m in mats], dtype=np.float64) * math.pi
    return np.clip(rho, 0.0, 1.0), emit


def _scene_bounds(cs: CompiledScene) -> tuple[np.ndarray, np.ndarray]:
    """A box around everything bounded in the scene (and the camera), to clip planes to."""
    return meshing.scene_bounds(cs.scene, cs.data.mesh_points.numpy() if cs.num_triangles else np.zeros((0, 3)))


def solid_angle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Solid angle of spherical triangles with unit corner directions a, b, c (rows): Van Oosterom and
    Strackee 1983, tan(E/2) = |a . (b x c)| / (1 + a.b + b.c + c.a)."""
    num = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    den = 1 + np.einsum("ij,ij->i", a, b) + np.einsum("ij,ij->i", b, c) + np.einsum("ij,ij->i", c, a)
    return 2 * np.arctan2(num, den)


def sphere_net(center, radius: float, patch_size: float) -> np.ndarray:
    """A latitude-longitude net of triangles inscribed in a sphere, wound outwards: (T, 3 corners, 3)."""
    n_lon, n_lat = (int(n) for n in meshing.sphere_segments(radius, patch_size))  # finite: check_limits ran
    theta = np.linspace(0.0, math.pi, n_lat + 1)
    phi = np.linspace(0.0, 2 * math.pi, n_lon + 1)

    def at(i: int, j: int) -> np.ndarray:
        t, f = theta[i], phi[j % n_lon]
        return np.asarray(center, float) + radius * np.array(
            [math.sin(t) * math.cos(f), math.cos(t), math.sin(t) * math.sin(f)]
        )

    tris = []
    for i in range(n_lat):
        for j in range(n_lon):
            a, b, c, d = at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)
            if i > 0:  # below the north pole's fan
                tris.append((a, b, c))
            if i < n_lat - 1:  # above the south pole's fan
                tris.append((a, c, d))
    tris = np.array(tris)
    outward = np.einsum(
        "ij,ij->i", np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), tris.mean(axis=1) - center
    )
    tris[outward < 0] = tris[outward < 0][:, [0, 2, 1]]
    return tris


def disk_net(center, normal, radius: float, patch_size: float) -> tuple[np.ndarray, float]:
    """Rings of triangles inscribed in a disk, wound along its normal: (T, 3 corners, 3), and the radius
    of the circle inside their polygon."""
    n_s, n_r = (int(n) for n in meshing.disk_segments(radius, patch_size))  # finite: check_limits ran
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t, b = meshing.tangents(n)
    c = np.asarray(center, float)

    def at(i: int, j: int) -> np.ndarray:
        f = 2 * math.pi * (j % n_s) / n_s
        return c + radius * i / n_r * (math.cos(f) * t + math.sin(f) * b)

    tris = []
    for i in range(n_r):
        for j in range(n_s):
            if i == 0:
                tris.append((c, at(1, j), at(1, j + 1)))
            else:
                tris.append((at(i, j), at(i + 1, j), at(i + 1, j + 1)))
                tris.append((at(i, j), at(i + 1, j + 1), at(i, j + 1)))
    tris = np.array(tris)
    along = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]) @ n
    tris[along < 0] = tris[along < 0][:, [0, 2, 1]]
    return tris, radius * math.cos(math.pi / n_s)


def triangles(cs: CompiledScene) -> meshing.Triangles:
    """The compiled scene's triangles: points, faces, the object of each face."""
    if not cs.num_triangles:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    faces = cs.data.mesh_indices.numpy().reshape(-1, 3)
    return cs.data.mesh_points.numpy(), faces, cs.data.face_obj.numpy()


def check_limits(cs: CompiledScene, settings) -> None:
    """Raise SceneError (at render.radiosity.patch_size or .rays) when a solve with `settings` (patch_size, rays,
    max_steps) is past the limits the scene was compiled under: counted before anything is meshed or shot."""
    problems = meshing.solve_problems(cs.scene, triangles(cs), settings, cs.limits)
    if problems:
        raise SceneError([{"path": f"render.radiosity.{field}", "message": message} for field, message in problems])


def build_patches(cs: CompiledScene, patch_size: float) -> Patches:
    """Mesh every object of the scene into patches of about patch_size (both sides of each)."""
    rho_m, emit_m = _material_rho(cs)
    mat_of = {name: i for i, name in enumerate(cs.material_names)}
    rows: list[tuple] = []  # (corner, e1, e2, triangle, obj, mat, area or None, sphere centre, sphere radius)
    n_obj = len(cs.scene.objects)
    object_kind = np.full(n_obj, int(PatchKind.FLAT), dtype=np.int32)
    object_center = np.zeros((n_obj, 3))
    object_radius = np.zeros(n_obj)

    def grid(c, e1, e2, obj, mat):
        c, e1, e2 = (np.asarray(v, float) for v in (c, e1, e2))
        nu, nv = (int(n) for n in meshing.grid_cells(e1, e2, patch_size))  # finite: check_limits ran
        for j in range(nv):
            for i in range(nu):
                rows.append((c + e1 * i / nu + e2 * j / nv, e1 / nu, e2 / nv, False, obj, mat, None, None, 0.0))

    def tri(v0, v1, v2, n, obj, mat):
        a, b = (v1 - v0) / n, (v2 - v0) / n
        for j in range(n):
            for i in range(n - j):
                rows.append((v0 + i * a + j * b, a, b, True, obj, mat, None, None, 0.0))
                if i + j < n - 1:  # the upside-down triangle of the cell, wound the same way
                    rows.append((v0 + (i + 1) * a + (j + 1) * b, -a, -b, True, obj, mat, None, None, 0.0))

    lo, hi = _scene_bounds(cs)
    for i, obj in enumerate(cs.scene.objects):
        mat = mat_of[obj.material] if isinstance(obj.material, str) else mat_of[f"objects[{i}].material"]
        if obj.type == "quad":
            grid(obj.corner, obj.edge1, obj.edge2, i, mat)
        elif obj.type == "box":
            for c, e1, e2 in meshing.box_faces(obj.min, obj.max, obj.transform):
                grid(c, e1, e2, i, mat)
        elif obj.type == "plane":
            grid(*meshing.plane_rect(obj.point, obj.normal, lo, hi), i, mat)
        elif obj.type == "sphere":
            centre = np.asarray(obj.center, float)
            net = sphere_net(centre, obj.radius, patch_size)
            dirs = (net - centre) / obj.radius
            areas = obj.radius**2 * solid_angle(dirs[:, 0], dirs[:, 1], dirs[:, 2])
            for (v0, v1, v2), area in zip(net, areas, strict=True):
                rows.append((v0, v1 - v0, v2 - v0, True, i, mat, area, centre, float(obj.radius)))
            object_kind[i], object_center[i], object_radius[i] = int(PatchKind.SPHERE), centre, obj.radius
        elif obj.type == "disk":
            net, inner = disk_net(obj.center, obj.normal, obj.radius, patch_size)
            flat = 0.5 * np.linalg.norm(np.cross(net[:, 1] - net[:, 0], net[:, 2] - net[:, 0]), axis=1)
            areas = flat * (math.pi * obj.radius**2 / flat.sum())  # the rim's slivers shared out
            for (v0, v1, v2), area in zip(net, areas, strict=True):
                rows.append((v0, v1 - v0, v2 - v0, True, i, mat, area, None, 0.0))
            object_kind[i], object_center[i], object_radius[i] = int(PatchKind.DISK), obj.center, inner * (1 - 1e-6)
    if cs.num_triangles:
        pts = cs.data.mesh_points.numpy().astype(float)
        idx = cs.data.mesh_indices.numpy().reshape(-1, 3)
        face_obj, face_mat = cs.data.face_obj.numpy(), cs.data.face_mat.numpy()
        cuts = meshing.triangle_cells(pts, idx, patch_size).astype(np.int64)
        for f, (i0, i1, i2) in enumerate(idx):
            tri(pts[i0], pts[i1], pts[i2], int(cuts[f]), int(face_obj[f]), int(face_mat[f]))
    if not rows:
        raise SceneError(
            [
                {
                    "path": "objects",
                    "message": "the radiosity integrator needs objects to mesh into patches; this scene has none",
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
    area = np.array(
        [r[6] if r[6] is not None else (0.5 if r[3] else 1.0) * ln for r, ln in zip(rows, length, strict=True)]
    )
    obj = np.array([r[4] for r in rows])
    mat = np.array([r[5] for r in rows])
    s_center = np.array([r[7] if r[7] is not None else np.zeros(3) for r in rows])
    s_radius = np.array([r[8] for r in rows])
    n = len(rows)

    def both(a: np.ndarray) -> np.ndarray:
        return np.concatenate([a, a])

    # both sides: patch k (front, the normal) and n + k (back); emission on the front side only
    return Patches(
        corner=both(corner),
        e1=both(e1),
        e2=both(e2),
        triangle=both(triangle),
        normal=np.concatenate([normal, -normal]),
        area=both(area),
        reflectance=both(rho_m[mat]),
        emission=np.concatenate([emit_m[mat], np.zeros_like(emit_m[mat])]),
        obj=both(obj),
        twin=np.concatenate([np.arange(n) + n, np.arange(n)]),
        sphere_center=both(s_center),
        sphere_radius=both(s_radius),
        object_kind=object_kind,
        object_center=object_center,
        object_radius=object_radius,
    )


def patch_index(p: Patches, device: str = "cpu") -> tuple[PatchIndex, list]:
    """The patches as triangles of one wp.Mesh, for `patch_at`; and the Warp objects to keep alive."""
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
    points = wp.array(np.array(pts, dtype=np.float32), dtype=wp.vec3, device=device)
    indices = wp.array(np.arange(len(pts), dtype=np.int32), dtype=wp.int32, device=device)
    mesh = wp.Mesh(points=points, indices=indices)
    tri_front = np.array(tri_front, dtype=np.int32)
    ix = PatchIndex()
    ix.mesh, ix.n = mesh.id, n
    ix.tri_patch = wp.array(tri_front, dtype=wp.int32, device=device)
    ix.tri_obj = wp.array(p.obj[tri_front].astype(np.int32), dtype=wp.int32, device=device)
    ix.obj_kind = wp.array(p.object_kind.astype(np.int32), dtype=wp.int32, device=device)
    ix.obj_center = wp.array(p.object_center.astype(np.float32), dtype=wp.vec3, device=device)
    ix.obj_radius = wp.array(p.object_radius.astype(np.float32), dtype=float, device=device)
    ix.max_dist = float(1e-3 * max(1.0, float(np.sqrt(p.area.max()))))
    return ix, [mesh, points, indices]
