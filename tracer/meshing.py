"""The surfaces' shapes in plain numpy: transforms, a box's faces, and the radiosity patches each surface
is cut into, counted from the geometry and `patch_size` before any meshing.

The renderer (tracer/kernels/compile.py) and the radiosity solve (tracer/radiosity/patches.py) place surfaces and
cut them with these functions, and validation (tracer/scene/model.py) counts the patches with the same ones,
so a scene refused for its number of patches is refused before a single patch is made, and the count is
the one the mesh would have:

- a parallelogram (a quad, a box face, a plane clipped to a box around the scene): ceil(|e1| / s) x
  ceil(|e2| / s) cells;
- a triangle (a triangle object, each triangle of a mesh): n x n smaller triangles, n = ceil(longest
  edge / s);
- a sphere: a latitude-longitude net of 2 x around x (rows - 1) triangles;
- a disk: rings of sectors x (2 x rings - 1) triangles.

Each count is at least 1 per surface, and each patch has two sides (front and back).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tracer.assets import AssetError, read_mesh

SPHERE_MIN_SEGMENTS = (12, 6)  # a sphere's net has at least this many triangles around, and rows from pole to pole
DISK_MIN_SECTORS = 16  # a disk's rings have at least this many sectors


# ----------------------------------------------------------------------------- transforms


def transform_matrix(t) -> np.ndarray:
    """4x4 matrix of a Transform: scale, then rotate about X, Y, Z (degrees), then translate."""
    m = np.eye(4)
    if t is None:
        return m
    s = np.diag([*t.scale, 1.0])
    rx, ry, rz = (math.radians(a) for a in t.rotate)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    mx = np.array([[1, 0, 0, 0], [0, cx, -sx, 0], [0, sx, cx, 0], [0, 0, 0, 1]])
    my = np.array([[cy, 0, sy, 0], [0, 1, 0, 0], [-sy, 0, cy, 0], [0, 0, 0, 1]])
    mz = np.array([[cz, -sz, 0, 0], [sz, cz, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    tr = np.eye(4)
    tr[:3, 3] = t.translate
    return tr @ mz @ my @ mx @ s


def apply(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Points (n, 3) through a 4x4 transform."""
    return pts @ m[:3, :3].T + m[:3, 3]


def box_faces(bmin, bmax, transform) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The six faces of a (transformed) box as (corner, edge1, edge2), edge1 x edge2 outwards."""
    m = transform_matrix(transform)
    lo, hi = np.asarray(bmin, float), np.asarray(bmax, float)
    centre = apply(m, ((lo + hi) / 2)[None])[0]
    faces = []
    for axis in range(3):
        a1, a2 = (axis + 1) % 3, (axis + 2) % 3
        for side in (lo, hi):
            c = lo.copy()
            c[axis] = side[axis]
            e1 = np.zeros(3)
            e1[a1] = hi[a1] - lo[a1]
            e2 = np.zeros(3)
            e2[a2] = hi[a2] - lo[a2]
            wc = apply(m, c[None])[0]
            we1 = m[:3, :3] @ e1
            we2 = m[:3, :3] @ e2
            if np.dot(np.cross(we1, we2), wc + 0.5 * (we1 + we2) - centre) < 0:
                we1, we2 = we2, we1
            faces.append((wc, we1, we2))
    return faces


def tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors that make a right-handed frame with the unit normal n."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(n, a)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t)


# ----------------------------------------------------------------------------- triangles


def mesh_triangles(objects: list, mesh_file=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every triangle the renderer builds, as compile_scene places them: (points (n, 3) as float32 values,
    faces (m, 3) into them, the object of each face). `mesh_file(i, obj)` gives a mesh file's (vertices,
    faces), or None where it is not known (validation without the asset folder): then it is left out."""
    pts, faces, owner, base = [], [], [], 0
    for i, obj in enumerate(objects):
        if obj.type == "triangle":
            v, f = np.asarray(obj.vertices, np.float64), np.array([[0, 1, 2]])
        elif obj.type == "mesh" and obj.file is None:
            v = apply(transform_matrix(obj.transform), np.asarray(obj.vertices, np.float64))
            f = np.asarray(obj.faces, np.int64)
        elif obj.type == "mesh" and mesh_file is not None and (read := mesh_file(i, obj)) is not None:
            v, f = apply(transform_matrix(obj.transform), np.asarray(read[0], np.float64)), np.asarray(read[1])
        else:
            continue
        pts.append(v.astype(np.float32))
        faces.append(f.reshape(-1, 3) + base)
        owner.append(np.full(len(f), i))
        base += len(v)
    if not pts:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    return np.concatenate(pts), np.concatenate(faces), np.concatenate(owner)


def mesh_files(folder: Path | None, max_triangles: int | None = None):
    """`mesh_triangles`' reader of mesh files from the asset folder (None: none is read); a file that does
    not read, or has more than `max_triangles`, is left out (validation reports it at its own field)."""
    if folder is None:
        return None

    def read(i: int, obj) -> tuple[np.ndarray, np.ndarray] | None:
        try:
            return read_mesh(obj.file, folder, max_triangles)[:2]
        except AssetError:
            return None

    return read


def scene_bounds(scene, mesh_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A box around everything bounded in the scene (and the camera), to clip planes to."""
    pts = [np.asarray(scene.camera.lookfrom, float), np.asarray(scene.camera.lookat, float)]
    for obj in scene.objects:
        for key in ("center", "corner", "min", "max"):
            if hasattr(obj, key):
                pts.append(np.asarray(getattr(obj, key), float))
        if obj.type in ("sphere", "disk"):
            pts += [np.asarray(obj.center, float) - obj.radius, np.asarray(obj.center, float) + obj.radius]
        if obj.type == "quad":
            pts.append(np.add(obj.corner, np.add(obj.edge1, obj.edge2)))
    for light in scene.lights:
        for key in ("position", "corner", "center"):
            if hasattr(light, key):
                pts.append(np.asarray(getattr(light, key), float))
    if len(mesh_points):
        pts.extend(np.asarray(mesh_points, np.float32).astype(float))
    p = np.array(pts)
    lo, hi = p.min(axis=0), p.max(axis=0)
    pad = 0.25 * (hi - lo).max() + 1e-3
    return lo - pad, hi + pad


# ----------------------------------------------------------------------------- how many patches


def cells(length: float, patch_size: float) -> int | float:
    """Patches along an edge of `length`: ceil(length / patch_size), at least 1 (inf past any float)."""
    q = float(length) / patch_size
    return max(1, math.ceil(q)) if math.isfinite(q) else math.inf


def grid_cells(e1, e2, patch_size: float) -> tuple[int | float, int | float]:
    """Cells of a parallelogram along e1 and along e2."""
    return cells(float(np.linalg.norm(e1)), patch_size), cells(float(np.linalg.norm(e2)), patch_size)


def plane_rect(point, normal, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The part of a plane that radiosity meshes: the rectangle (corner, e1, e2) in the plane that covers
    the box lo..hi seen along the normal."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t, b = tangents(n)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    rel = corners - np.asarray(point, float)
    u, v = rel @ t, rel @ b
    origin = np.asarray(point, float) + u.min() * t + v.min() * b
    return origin, (u.max() - u.min()) * t, (v.max() - v.min()) * b


def sphere_segments(radius: float, patch_size: float) -> tuple[int | float, int | float]:
    """(around, rows from pole to pole) of a sphere's net."""
    around = max(SPHERE_MIN_SEGMENTS[0], cells(2 * math.pi * radius, patch_size))
    rows = max(SPHERE_MIN_SEGMENTS[1], cells(math.pi * radius, patch_size))
    return around, rows


def disk_segments(radius: float, patch_size: float) -> tuple[int | float, int | float]:
    """(sectors, rings) of a disk's net."""
    return max(DISK_MIN_SECTORS, cells(2 * math.pi * radius, patch_size)), cells(radius, patch_size)


def triangle_cells(points: np.ndarray, faces: np.ndarray, patch_size: float) -> np.ndarray:
    """n of each triangle (faces (m, 3) into points (n, 3)), cut into n x n: ceil(longest edge / patch_size),
    at least 1 (float64: inf past any float)."""
    p = np.asarray(points, np.float64)
    longest = np.zeros(len(faces))
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = p[faces[:, b]] - p[faces[:, a]]
        np.maximum(longest, np.sqrt(np.einsum("ij,ij->i", d, d)), out=longest)
    with np.errstate(over="ignore"):
        return np.maximum(1.0, np.ceil(longest / patch_size))


Triangles = tuple[np.ndarray, np.ndarray, np.ndarray]  # points (n, 3), faces (m, 3), the object of each face


def patch_counts(scene, patch_size: float, triangles: Triangles) -> dict[int, float]:
    """Object index -> how many patches (pieces of surface, two sides each) radiosity meshing makes of it,
    with the scene's `triangles` (`mesh_triangles`, or a compiled scene's). Counted from the geometry
    alone: nothing is meshed."""
    points, faces, owner = triangles
    counts: dict[int, float] = {}
    lo, hi = scene_bounds(scene, points)
    for i, obj in enumerate(scene.objects):
        if obj.type == "quad":
            nu, nv = grid_cells(obj.edge1, obj.edge2, patch_size)
            counts[i] = nu * nv
        elif obj.type == "box":
            box = box_faces(obj.min, obj.max, obj.transform)
            counts[i] = sum(math.prod(grid_cells(e1, e2, patch_size)) for _, e1, e2 in box)
        elif obj.type == "plane":
            _, e1, e2 = plane_rect(obj.point, obj.normal, lo, hi)
            nu, nv = grid_cells(e1, e2, patch_size)
            counts[i] = nu * nv
        elif obj.type == "sphere":
            around, rows = sphere_segments(obj.radius, patch_size)
            counts[i] = 2 * around * (rows - 1)
        elif obj.type == "disk":
            sectors, rings = disk_segments(obj.radius, patch_size)
            counts[i] = sectors * (2 * rings - 1)
    if len(faces):
        n = triangle_cells(points, faces, patch_size)
        per = np.bincount(owner, weights=n * n, minlength=len(scene.objects))
        for i in np.flatnonzero(per):
            counts[int(i)] = float(per[i])
    return counts


def solve_problems(scene, triangles: Triangles, settings, limits) -> list[tuple[str, str]]:
    """(the field of render.radiosity, what is wrong) of each limit a radiosity solve of `scene` with
    `settings` (patch_size, rays, max_steps) is past: `limits.max_solve_rays`, `limits.max_patches`.
    Checked before anything is meshed or shot."""
    out = []
    most = settings.rays * settings.max_steps
    if most > limits.max_solve_rays:
        out.append((
            "rays",
            f"rays x max_steps = {settings.rays} x {settings.max_steps} = {most} form-factor rays at most; "
            f"{limits.at_most('max_solve_rays')}: use fewer rays or fewer steps",
        ))  # fmt: skip
    counts = patch_counts(scene, settings.patch_size, triangles)
    total = sum(counts.values())
    if total > limits.max_patches:
        biggest = sorted(counts.items(), key=lambda item: -item[1])[:3]
        where = ", ".join(f"objects[{i}] ({scene.objects[i].type}): {_number(n)}" for i, n in biggest)
        out.append((
            "patch_size",
            f"patches of {settings.patch_size:g} cut the surfaces into {_number(total)} patches ({where}); "
            f"{limits.at_most('max_patches')}: use a larger patch_size",
        ))  # fmt: skip
    return out


def _number(n: float) -> str:
    return f"{n:.0f}" if n < 1e15 else f"{n:.3g}"
