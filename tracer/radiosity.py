"""Radiosity by progressive refinement with ray-cast form factors (Goral et al. 1984; Cohen et al. 1988).

Every surface the solve sees is cut into patches of about `patch_size` world units: quads, box
faces, planes (clipped to the scene's bounds), triangles and meshes into parallelograms and
triangles; spheres into a latitude-longitude net of triangles inscribed in them; disks into rings
of triangles. Every surface is two-sided, so each piece of surface is two patches, one per side,
each with its own radiosity. A patch of a sphere or a disk stands for the piece of the curved
surface it covers: its area is that piece's area (a spherical triangle's area is r^2 times its
solid angle), and it shoots from points of the true surface, so nothing is lost to the facets.

Progressive refinement: the patch (or light) with the most unshot power shoots it. The form factors
from the shooter to everything else are estimated by casting rays (Malley's method): `rays` points
uniformly on the shooter, cosine-weighted directions about its normal, each carrying an equal share
of the power to the first surface it meets, found with the scene's own geometry (`closest_hit`) and
mapped to the patch there (`patch_at`). A patch that receives power P keeps rho P in its radiosity
and unshot power, and absorbs (1 - rho) P; area lights are black and absorb what reaches them; rays
that leave the scene (or the meshed part of a plane) take their power out of the solution
("escaped"). So, exactly at every step:

    emitted = absorbed + unshot + escaped                                  (per RGB channel)

Each shot's rays run in parallel (one band of rays per thread); every ray writes the patch it
reached, and the patches count their rays, so the sums never depend on the threads.

Sources: area lights (power = pi radiance area, shot from points on the light), emissive
materials (a patch's own exitance, pi emission), and point, spot and directional lights, whose
power reaching each patch is computed directly (one shadow ray to the patch centre); for those,
"emitted" counts only the power that reaches a patch.

Units: radiosity B is exitance, W/m^2; the radiance a diffuse patch sends out is B / pi.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import warp as wp

from tracer import meshing
from tracer.compile import CompiledScene, compile_scene
from tracer.errors import Cancelled
from tracer.geometry import PI, closest_hit
from tracer.kinds import (
    PATCHES_DISK,
    PATCHES_FLAT,
    PATCHES_NONE,
    PATCHES_SPHERE,
    RAD_FLAT,
    RAD_TWO_PASS,
    RAY_OFFSET,
    SHOOT_PATCH,
    T_FAR,
    PatchKind,
    RadDisplay,
    Shooter,
    Texture,
)
from tracer.lights import light_at, surface_point
from tracer.parallel import BandLauncher, default_threads
from tracer.sampling import rng_start, sample_cosine_hemisphere, to_world
from tracer.scene import AREA_LIGHTS, Scene, SceneError
from tracer.structs import PatchIndex, RadiosityData, SceneData

LIGHT_RAYS_PER_PATCH = 256  # an area light shoots at least this many rays per patch side
SNAPSHOT_EVERY_STEP = 16  # snapshots of B after every shot up to this many, then after 32, 64, 128, ...
SPHERE_MIN_SEGMENTS = meshing.SPHERE_MIN_SEGMENTS  # a sphere's net: at least this many triangles around, and rows
DISK_MIN_SECTORS = meshing.DISK_MIN_SECTORS  # a disk's rings have at least this many sectors
SPHERE_REACH = wp.constant(1.001)  # a ray from a sphere's centre to its facets (inscribed) goes this far, in radii
TARGET_ESCAPED = wp.constant(-1)  # a ray that left the scene (or reached a surface that has no patches)
TARGET_LIGHT = wp.constant(-2)  # a ray that ended on an area light (black: absorbed)


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
    threshold: float = 0.01  # the solve stops when unshot < threshold x emitted ...
    max_steps: int = 2000  # ... or after this many shots
    rays: int = 0  # rays cast so far (form factors and the point lights' shadow rays)
    seconds: float = 0.0  # time spent solving so far
    reported: float = 0.0  # the largest fraction() said so far (progress never goes back)
    cached: bool = False  # read from a SolutionCache rather than solved here
    corners: np.ndarray | None = None  # (2 x 3 per patch-mesh triangle, 3) B at the corners (`attach`)
    corners_ind: np.ndarray | None = None  # the same for the interreflected part

    def unshot_total(self) -> float:
        return float(self.unshot.sum())

    def fraction(self) -> float:
        """How far the solve has come, 0..1, never less than said before: the shots against max_steps,
        or the shots so far against the shots to go, estimated from how fast the unshot power has been
        falling over the last quarter of the shots (it falls ever more slowly as it spreads over the
        patches), whichever is further."""
        steps = len(self.history)
        estimate = min(1.0, steps / max(self.max_steps, 1))
        emitted = float(self.emitted.sum())
        left = self.unshot_total() / emitted if emitted > 0 else 1.0
        first = sum(1 for h in self.history if isinstance(h["shooter"], str))  # the lights' shots
        shots = steps - first
        if self.direct is not None and left <= self.threshold:
            estimate = 1.0
        elif self.direct is not None and shots >= 2 and left > 0:
            back = max(1, shots // 4)
            before = self.history[steps - 1 - back]["unshot"] / emitted
            rate = (math.log(max(before, 1e-300)) - math.log(left)) / back  # log of the unshot power, per shot
            if rate > 0:
                estimate = max(estimate, shots / (shots + math.log(left / self.threshold) / rate))
        self.reported = float(min(1.0, max(self.reported, estimate)))
        return self.reported

    def stats(self) -> dict:
        """What the solve cost: shots, rays, seconds, and the share of the power still unshot."""
        emitted = float(self.emitted.sum())
        return {
            "patches": len(self.patches),
            "shots": len(self.history),
            "rays": int(self.rays),
            "seconds": round(self.seconds, 4),
            "unshot": self.unshot_total() / emitted if emitted > 0 else 0.0,
            "cached": self.cached,
        }

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
            "stats": self.stats(),
        }


# ----------------------------------------------------------------------------------------- meshing


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
    n_lon, n_lat = meshing.sphere_segments(radius, patch_size)
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
    n_s, n_r = meshing.disk_segments(radius, patch_size)
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
        nu, nv = meshing.grid_cells(e1, e2, patch_size)
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


@wp.func(inline=True)
def patch_at(ix: PatchIndex, p: wp.vec3, nf: wp.vec3, obj: int):
    """The radiosity patch side under the point p of object obj (at time 0), on the side nf points to:
    (patch side k, its triangle in ix.mesh, barycentrics u, v there), or k = -1 off the patches (an area
    light, a plane beyond the meshed part, an object the solve does not see).

    Flat surfaces lie on their facets: the nearest facet. A sphere's facets are inscribed in it: the
    facet that the ray from the centre through p crosses. A disk's rim bulges past its polygon of
    facets: the point is first pulled radially inside the polygon."""
    face = int(-1)
    u = float(0.0)
    v = float(0.0)
    kind = PATCHES_NONE
    if obj >= 0:
        kind = ix.obj_kind[obj]
    if kind == PATCHES_SPHERE:
        c = ix.obj_center[obj]
        qr = wp.mesh_query_ray(ix.mesh, c, wp.normalize(p - c), ix.obj_radius[obj] * SPHERE_REACH)
        if qr.result:
            face = qr.face
            u = qr.u
            v = qr.v
    elif kind == PATCHES_FLAT or kind == PATCHES_DISK:
        x = p
        if kind == PATCHES_DISK:
            c = ix.obj_center[obj]
            r = wp.length(p - c)
            if r > ix.obj_radius[obj]:
                x = c + (p - c) * (ix.obj_radius[obj] / r)
        q = wp.mesh_query_point_no_sign(ix.mesh, x, ix.max_dist)
        if q.result:
            face = q.face
            u = q.u
            v = q.v
    if face < 0:
        return -1, -1, u, v
    if ix.tri_obj[face] != obj:  # a different surface just as close (a light on a ceiling)
        return -1, -1, u, v
    k = ix.tri_patch[face]
    if wp.dot(wp.mesh_eval_face_normal(ix.mesh, face), nf) < 0.0:  # the back side
        k = k + ix.n
    return k, face, u, v


@wp.func(inline=True)
def radiosity_at(rad: RadiosityData, p: wp.vec3, nf: wp.vec3, obj: int):
    """The radiosity solution at a hit at p on object obj, seen from the side nf points to:
    (1, B, the interreflected part of B, rho), or (0, ...) off the patches (see `patch_at`).
    B and its interreflected part are the patch's own values in the flat display, else
    interpolated from the patch's corners (smooth display, two-pass shading)."""
    zero = wp.vec3(0.0)
    k, face, u, v = patch_at(rad.index, p, nf, obj)
    if k < 0:
        return 0, zero, zero, zero
    b = rad.radiosity[k]
    ind = rad.indirect[k]
    if rad.mode != RAD_FLAT:  # smooth display, and the two-pass interreflection: interpolated at the corners
        c = 3 * face
        if k >= rad.index.n:  # the back side's corners follow the front sides'
            c = c + 3 * rad.index.tri_patch.shape[0]
        w = 1.0 - u - v
        b = u * rad.corners[c] + v * rad.corners[c + 1] + w * rad.corners[c + 2]
        ind = u * rad.corners_ind[c] + v * rad.corners_ind[c + 1] + w * rad.corners_ind[c + 2]
    return 1, b, ind, rad.rho[k]


@wp.func
def safe_div(a: wp.vec3, b: wp.vec3) -> wp.vec3:
    return wp.vec3(
        wp.where(b[0] > 0.0, a[0] / b[0], 0.0),
        wp.where(b[1] > 0.0, a[1] / b[1], 0.0),
        wp.where(b[2] > 0.0, a[2] / b[2], 0.0),
    )


@wp.func(inline=True)
def radiosity_ambient(rad: RadiosityData, kd: wp.vec3, p: wp.vec3, nf: wp.vec3, obj: int):
    """What the solution puts in place of the ambient term at a hit (kd the diffuse colour there):
    (radiance, 1 if it is the patch's own radiance and replaces the whole local term).

    Two-pass display: kd / pi times the interreflected irradiance (the interreflected B over the patch's
    rho), so the ray tree adds the direct light and the mirrors. Flat and smooth displays: B / pi, the
    radiance of the patch itself. Off the patches: no ambient term."""
    found, b, ind, rho = radiosity_at(rad, p, nf, obj)
    if found == 0:
        return wp.vec3(0.0), 0
    if rad.mode == RAD_TWO_PASS:
        return wp.cw_mul(kd, safe_div(ind, rho)) / PI, 0
    return b / PI, 1


# ----------------------------------------------------------------------------------------- kernels


@wp.kernel
def shoot(
    scene: SceneData,
    ix: PatchIndex,
    shooter: int,  # SHOOT_PATCH: a patch side (corner, e1, e2, triangle flag; on a sphere); SHOOT_LIGHT
    corner: wp.vec3,
    e1: wp.vec3,
    e2: wp.vec3,
    tri: int,
    sphere_center: wp.vec3,
    sphere_radius: float,  # > 0: the patch stands for the piece of this sphere above it
    light_index: int,
    seed: int,
    step: int,
    first: int,  # this launch casts rays first, first + 1, ... of the shot's n_rays
    n_rays: int,
    target: wp.array(dtype=wp.int32),
):
    """One ray of a shot per thread: from a point of the shooter, in a cosine-weighted direction about
    its normal, to the first surface; writes the patch side it reached (or TARGET_*) at its index."""
    r = first + wp.tid()
    rng = rng_start(seed, step, r)
    m = int(wp.floor(wp.sqrt(float(n_rays))))
    u1 = wp.randf(rng)
    u2 = wp.randf(rng)
    if r < m * m:  # stratified positions on the shooter
        u1 = (float(r % m) + u1) / float(m)
        u2 = (float(r / m) + u2) / float(m)
    p = wp.vec3(0.0)
    n = wp.vec3(0.0, 1.0, 0.0)
    if shooter == SHOOT_PATCH:
        a = u1
        b = u2
        if tri != 0 and a + b > 1.0:
            a = 1.0 - a
            b = 1.0 - b
        p = corner + a * e1 + b * e2
        n = wp.normalize(wp.cross(e1, e2))
        if sphere_radius > 0.0:  # the point of the sphere above the facet's point, and the sphere's normal
            radial = wp.normalize(p - sphere_center)
            p = sphere_center + sphere_radius * radial
            n = wp.where(wp.dot(radial, n) < 0.0, -radial, radial)
    else:
        p, n = surface_point(scene.lights[light_index], u1, u2)
    d = to_world(sample_cosine_hemisphere(wp.randf(rng), wp.randf(rng)), n)
    h = closest_hit(scene, p + RAY_OFFSET * n, d, T_FAR, 0.0)
    out = int(TARGET_ESCAPED)
    if h.hit != 0:
        if h.obj < 0:
            out = TARGET_LIGHT
        else:
            nf = wp.where(wp.dot(d, h.ng) < 0.0, h.ng, -h.ng)  # the true surface's side the ray arrives on
            k, face, bu, bv = patch_at(ix, h.po, nf, h.obj)
            out = k
    target[r] = out


@wp.kernel
def direct(
    scene: SceneData,
    points: wp.array(dtype=wp.vec3),
    normals: wp.array(dtype=wp.vec3),
    light_index: int,
    first: int,
    received: wp.array(dtype=wp.vec3),
):
    """Irradiance of a point, spot or directional light at each patch side's centre (one shadow ray)."""
    i = first + wp.tid()
    light = scene.lights[light_index]
    p = points[i]
    n = normals[i]
    l, dist, e, reaches = light_at(light, p)
    cos = wp.dot(n, l)
    if reaches != 0 and cos > 0.0:
        o = p + RAY_OFFSET * n
        h = closest_hit(scene, o, l, dist, 0.0)
        if h.hit == 0:
            received[i] = e * cos  # W/m^2; times the area outside


# ----------------------------------------------------------------------------------------- solver


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


def solve(
    scene: Scene | CompiledScene,
    patch_size: float = 0.25,
    rays: int = 4096,
    threshold: float = 0.01,
    max_steps: int = 2000,
    seed: int = 0,
    on_step=None,
    cancel=None,
    threads: int | None = None,
    device: str = "cpu",
) -> Solution:
    """Progressive refinement until the unshot power is below `threshold` of the emitted power (or
    `max_steps` shots). `on_step(solution, step)` is called after each shot; `cancel()` before each
    one (True raises `Cancelled`). The shots' rays run on `threads` threads (default: every core); on a
    CUDA device each shot is one launch."""
    start = time.perf_counter()
    cs = scene if isinstance(scene, CompiledScene) else compile_scene(scene, device=device)
    check_limits(cs, SimpleNamespace(patch_size=patch_size, rays=rays, max_steps=max_steps))
    p = build_patches(cs, patch_size)
    ix, keep = patch_index(p, device)
    n = len(p)
    unshot = p.emission * p.area[:, None]
    sol = Solution(p, p.emission.copy(), unshot, unshot.sum(axis=0), np.zeros(3), np.zeros(3))
    sol.threshold, sol.max_steps = threshold, max_steps
    launch = BandLauncher(threads or default_threads(), device)

    def receive(power_in: np.ndarray) -> None:
        kept = p.reflectance * power_in
        sol.radiosity += kept / p.area[:, None]
        sol.unshot += kept
        sol.absorbed += (power_in - kept).sum(axis=0)

    def shot_done(step: int, entry: dict) -> None:
        sol.history.append({"step": step, **entry, "unshot": sol.unshot_total()})
        sol.seconds = time.perf_counter() - start
        if on_step:
            on_step(sol, step)

    def check_cancel() -> None:
        if cancel is not None and cancel():
            raise Cancelled()

    try:
        step = 0
        # 1. point, spot and directional lights: their power reaching each patch, directly
        points, normals = p.surface_points()
        points = wp.array(points.astype(np.float32), dtype=wp.vec3, device=device)
        normals = wp.array(normals.astype(np.float32), dtype=wp.vec3, device=device)
        received = wp.zeros(n, dtype=wp.vec3, device=device)
        for li, light in enumerate(cs.scene.lights):
            if not isinstance(light, AREA_LIGHTS):
                check_cancel()
                received.zero_()
                launch(direct, n, lambda first, li=li: [cs.data, points, normals, li, first, received])
                power_in = received.numpy().astype(np.float64) * p.area[:, None]
                sol.emitted += power_in.sum(axis=0)
                sol.rays += n
                receive(power_in)
                shot_done(step, {"shooter": f"lights[{li}]"})
                step += 1
        # 2. area lights: shoot their whole power (pi L A)
        for li, light in enumerate(cs.scene.lights):
            if isinstance(light, AREA_LIGHTS):
                check_cancel()
                area = float(cs.data.lights.numpy()[li]["area"])
                power = np.asarray(light.radiance, float) * math.pi * area
                sol.emitted += power
                # the lights' shots make the directly lit part: enough rays for every patch to get its share
                _shoot(
                    sol,
                    cs,
                    ix,
                    launch,
                    Shooter.LIGHT,
                    None,
                    li,
                    seed,
                    step,
                    max(rays, LIGHT_RAYS_PER_PATCH * n),
                    power,
                    receive,
                )
                shot_done(step, {"shooter": f"lights[{li}]"})
                step += 1
        sol.direct = sol.radiosity.copy()
        # 3. progressive refinement: the patch with the most unshot power shoots it
        sol.snapshots[step] = sol.radiosity.copy()
        while step < max_steps and sol.unshot_total() > threshold * float(sol.emitted.sum()):
            check_cancel()
            k = int(np.argmax(sol.unshot.sum(axis=1)))
            power = sol.unshot[k].copy()
            sol.unshot[k] = 0.0
            _shoot(sol, cs, ix, launch, Shooter.PATCH, k, -1, seed, step, rays, power, receive)
            shot_done(step, {"shooter": k, "power": float(power.sum())})
            step += 1
            if step <= SNAPSHOT_EVERY_STEP or step & (step - 1) == 0:  # every early shot, then 32, 64, ...
                sol.snapshots[step] = sol.radiosity.copy()
        sol.snapshots[step] = sol.radiosity.copy()  # and the final solution
    finally:
        launch.close()
    sol.seconds = time.perf_counter() - start
    del keep
    return sol


def _shoot(sol, cs, ix, launch, shooter, k, li, seed, step, rays, power, receive) -> None:
    """One shot of `power` (W, RGB) in `rays` rays from patch side k or area light li."""
    p = sol.patches
    zero = wp.vec3(0.0)
    args = [zero, zero, zero, 0, zero, 0.0]
    if shooter == Shooter.PATCH:
        e1, e2 = (p.e1[k], p.e2[k]) if k < len(p) // 2 else (p.e2[k], p.e1[k])  # a back side: flip its edges
        args = [wp.vec3(*p.corner[k]), wp.vec3(*e1), wp.vec3(*e2), int(p.triangle[k])]
        args += [wp.vec3(*p.sphere_center[k]), float(p.sphere_radius[k])]
    target = wp.empty(rays, dtype=wp.int32, device=launch.device)
    launch(shoot, rays, lambda first: [cs.data, ix, int(shooter), *args, li, seed, step, first, rays, target])
    hits = target.numpy()
    counts = np.bincount(hits[hits >= 0], minlength=len(p))
    share = power / rays
    power_in = counts[:, None] * share[None, :]
    light = int(np.count_nonzero(hits == TARGET_LIGHT))
    escaped = rays - int(counts.sum()) - light
    sol.escaped += escaped * share
    sol.absorbed += light * share
    sol.rays += rays
    receive(power_in)


# ----------------------------------------------------------------------------------------- display


def corner_values(p: Patches, values: np.ndarray) -> np.ndarray:
    """Per patch side, the values at its triangle corners (2 triangles for a parallelogram), each the
    mean of the values of the same object's patches on the same side that share that corner (smooth
    shading of a piecewise-constant solution). Flat pieces share corners only with pieces facing the
    same way (no smoothing over a box's edges); a sphere's facets all share theirs.
    Returns (sides, 6, 3): corners of up to 2 triangles, in the order `patch_index` emits them."""
    n2 = len(p)
    quads = ~p.triangle
    c, a, b = p.corner, p.e1, p.e2
    tri_pts = np.where(
        quads[:, None, None],
        np.stack([c, c + a, c + a + b, c, c + a + b, c + b], axis=1),
        np.stack([c, c + a, c + b, c, c, c], axis=1),
    )
    facing = np.round(p.normal * 1e3).astype(np.int64)
    back = (np.arange(n2) >= n2 // 2).astype(np.int64)
    facing[p.sphere_radius > 0] = back[p.sphere_radius > 0, None]  # a sphere: front or back only
    key_pts = np.round(tri_pts / 1e-6).astype(np.int64)
    used = np.ones((n2, 6), dtype=bool)
    used[~quads, 3:] = False  # a triangle has 3 corners
    # one row per (patch, corner): the corner's group (object, facing) and its point; equal rows share
    rows = np.concatenate(
        [np.repeat(np.column_stack([p.obj.astype(np.int64), facing])[:, None, :], 6, axis=1), key_pts], axis=2
    )
    _, inverse = np.unique(rows[used], axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    weight = np.repeat(p.area[:, None], 6, axis=1)[used]
    sums = np.zeros((inverse.max() + 1, 3))
    np.add.at(sums, inverse, weight[:, None] * np.repeat(values[:, None, :], 6, axis=1)[used])
    counts = np.zeros(inverse.max() + 1)
    np.add.at(counts, inverse, weight)
    out = np.zeros((n2, 6, 3))
    out[used] = sums[inverse] / counts[inverse, None]
    return out


class SolutionCache:
    """Radiosity solutions on disk, by the content of what they solve: a second render or ray tree of the
    same scene (whatever its camera's view, film or sampler) reads the solution in milliseconds
    instead of solving it again. At most `keep` solutions; the least recently used go first."""

    def __init__(self, folder: Path | str, keep: int = 64):
        self.folder, self.keep = Path(folder), keep

    @staticmethod
    def key(cs: CompiledScene) -> str:
        """A hash of everything the solve depends on: the flattened shapes, triangles, materials (their
        textures' pixels too), lights, the solve's settings and seed, the camera's position (planes are
        clipped to a box that holds it), and this module's code."""
        h = hashlib.sha256()
        d = cs.data
        for arr in (d.shapes, d.materials, d.lights, d.mesh_points, d.mesh_indices, d.face_obj, d.face_mat):
            h.update(arr.numpy().tobytes())
        h.update(d.tex_pixels.numpy().tobytes())
        sc = cs.scene
        meta = {
            "radiosity": sc.render.radiosity.model_dump(mode="json"),
            "seed": sc.render.seed,
            "camera": [sc.camera.lookfrom, sc.camera.lookat],
            "objects": [o.type for o in sc.objects],
            "names": cs.material_names,
        }
        h.update(json.dumps(meta, sort_keys=True).encode())
        h.update(Path(__file__).read_bytes())
        return h.hexdigest()[:32]

    def has(self, key: str) -> bool:
        """Is a solution of this key kept?"""
        return (self.folder / f"{key}.npz").is_file()

    def get(self, key: str) -> Solution | None:
        path = self.folder / f"{key}.npz"
        try:
            with np.load(path, allow_pickle=False) as z:
                sol = _solution_from(dict(z))
        except (OSError, ValueError, KeyError):
            return None
        path.touch()  # recently used
        return sol

    def put(self, key: str, sol: Solution) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = self.folder / f".{key}.{os.getpid()}.npz"
        with open(tmp, "wb") as f:
            np.savez(f, **_solution_arrays(sol))
        os.replace(tmp, self.folder / f"{key}.npz")
        files = sorted(self.folder.glob("*.npz"), key=lambda p: p.stat().st_mtime)
        for old in files[: max(0, len(files) - self.keep)]:
            old.unlink(missing_ok=True)


PATCH_FIELDS = [f.name for f in fields(Patches)]


def _solution_arrays(sol: Solution) -> dict[str, np.ndarray]:
    out = {f"patches.{name}": np.asarray(getattr(sol.patches, name)) for name in PATCH_FIELDS}
    for name in ("radiosity", "unshot", "emitted", "absorbed", "escaped", "direct"):
        out[name] = np.asarray(getattr(sol, name))
    out["corners"], out["corners_ind"] = np.asarray(sol.corners), np.asarray(sol.corners_ind)
    steps = sorted(sol.snapshots)
    out["snapshot_steps"] = np.asarray(steps, dtype=np.int64)
    out["snapshots"] = np.stack([sol.snapshots[k] for k in steps]) if steps else np.zeros((0, len(sol.patches), 3))
    scalars = {"threshold": sol.threshold, "max_steps": sol.max_steps, "rays": sol.rays, "seconds": sol.seconds}
    out["meta"] = np.asarray(json.dumps({"history": sol.history, **scalars}))
    return out


def _solution_from(z: dict) -> Solution:
    patches = Patches(**{name: z[f"patches.{name}"] for name in PATCH_FIELDS})
    meta = json.loads(str(z["meta"]))
    sol = Solution(patches, z["radiosity"], z["unshot"], z["emitted"], z["absorbed"], z["escaped"], meta["history"])
    sol.direct = z["direct"]
    sol.snapshots = {int(k): v for k, v in zip(z["snapshot_steps"], z["snapshots"], strict=True)}
    sol.threshold, sol.max_steps, sol.rays, sol.seconds = (
        meta["threshold"],
        meta["max_steps"],
        meta["rays"],
        meta["seconds"],
    )
    sol.reported, sol.cached = 1.0, True
    sol.corners, sol.corners_ind = z["corners"], z["corners_ind"]
    return sol


def attach(
    cs: CompiledScene,
    device: str = "cpu",
    threads: int | None = None,
    on_step=None,
    cancel=None,
    cache: SolutionCache | None = None,
) -> Solution:
    """Solve the scene's radiosity (render.radiosity settings), or read it from `cache`, and put it in
    cs.data.rad for the kernels; the Solution stays in cs.radiosity (the patches, the convergence
    curve). `on_step` and `cancel` as in `solve`."""
    cfg = cs.scene.render.radiosity
    key = cache.key(cs) if cache is not None else None
    sol = cache.get(key) if cache is not None else None
    if sol is None:
        sol = solve(
            cs,
            patch_size=cfg.patch_size,
            rays=cfg.rays,
            threshold=cfg.threshold,
            max_steps=cfg.max_steps,
            seed=cs.scene.render.seed,
            on_step=on_step,
            cancel=cancel,
            threads=threads,
            device=device,
        )
    p = sol.patches
    ix, keep = patch_index(p, device)
    indirect = np.maximum(sol.radiosity - sol.direct, 0.0)
    if sol.corners is None:  # the smooth shading's corner values, kept with a cached solution
        sol.corners = _triangle_corners(ix, p, corner_values(p, sol.radiosity))
        sol.corners_ind = _triangle_corners(ix, p, corner_values(p, indirect))
        if cache is not None:
            cache.put(key, sol)
    r = RadiosityData()
    r.active = 1
    r.mode = int(RadDisplay[cfg.display.replace("-", "_").upper()])
    r.index = ix
    r.corners = wp.array(sol.corners, dtype=wp.vec3, device=device)
    r.corners_ind = wp.array(sol.corners_ind, dtype=wp.vec3, device=device)
    r.radiosity = wp.array(sol.radiosity.astype(np.float32), dtype=wp.vec3, device=device)
    r.indirect = wp.array(indirect.astype(np.float32), dtype=wp.vec3, device=device)
    r.rho = wp.array(p.reflectance.astype(np.float32), dtype=wp.vec3, device=device)
    cs.data.rad = r
    cs.keep += keep
    cs.radiosity = sol
    return sol


def _triangle_corners(ix: PatchIndex, p: Patches, corners: np.ndarray) -> np.ndarray:
    """(2 x 3 per triangle of the patch mesh) corner values: every front triangle, then every back one."""
    n = len(p) // 2
    tri_patch = ix.tri_patch.numpy()
    out = []
    for offset in (0, n):
        seen: dict = {}
        for k in tri_patch:
            first = seen.get(int(k), 0)  # a parallelogram's first or second triangle
            out.append(corners[k + offset, 3 * first : 3 * first + 3])
            seen[int(k)] = first + 1
    return np.concatenate(out).astype(np.float32)
