"""Scene models -> flat Warp arrays, in this one place.

Everything a kernel reads about a scene is in one ``@wp.struct SceneData`` of arrays and scalars:
analytic shapes (spheres, planes, parallelograms, disks; a box becomes six parallelograms),
all triangles in one ``wp.Mesh`` with its BVH, materials, lights and texture images. Scene
content is data only: no kernel source is ever generated from a scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp

from tracer.assets import (  # noqa: F401 (load_mesh_file: re-exported)
    ASSET_DIR,
    AssetError,
    image_size,
    load_image,
    load_mesh_file,
)
from tracer.kernels.filters import filter_tables
from tracer.kernels.kinds import Bump, FilterKind, Integrator, SamplerKind, Shape, Texture
from tracer.kernels.lights import light_data, light_shape
from tracer.kernels.structs import (
    FACE_SMOOTH,
    FACE_UV,
    CameraData,
    LightData,
    MaterialData,
    SceneData,
    ShapeData,
    inactive_radiosity,
    unit,
    vec3,
)
from tracer.meshing import apply as _apply
from tracer.meshing import box_faces, transform_matrix  # noqa: F401 (box_faces: re-exported)
from tracer.scene import AREA_LIGHTS, Limits, Material, Scene, SceneError, json_path, texture_problem


@dataclass
class CompiledScene:
    """The Warp-side scene plus what Python needs to explain it (names for the ray tree)."""

    scene: Scene
    data: SceneData
    object_names: list[str | None]
    material_names: list[str]
    num_triangles: int
    num_shapes: int
    keep: list = field(default_factory=list)  # Warp objects that must outlive `data` (the mesh)
    radiosity: object = None  # the radiosity.Solution when the integrator is radiosity
    limits: Limits = field(default_factory=Limits)  # what it was compiled under (the radiosity solve's too)


# ----------------------------------------------------------------------------- meshes


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (faces oriented by their vertex order)."""
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    vn = np.zeros_like(verts)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    n = np.linalg.norm(vn, axis=1, keepdims=True)
    return vn / np.where(n > 0, n, 1.0)


# ----------------------------------------------------------------------------- textures


class _Images:
    """Texture images, loaded once each, packed into one linear-RGB array. Each is counted against the
    limits (one image, and all of the scene's together) from its header before its pixels are decoded."""

    def __init__(self, asset_dir: Path, limits: Limits):
        self.asset_dir, self.limits = asset_dir, limits
        self.index: dict[str, int] = {}
        self.pixels: list[np.ndarray] = []
        self.info: list[tuple[int, int, int]] = []
        self.offset = 0

    def add(self, file: str, path: str) -> int:
        if file in self.index:
            return self.index[file]
        try:
            width, height = image_size(file, self.asset_dir)
        except AssetError as e:
            raise SceneError([{"path": path, "message": e.message}]) from None
        problem = texture_problem(width, height, self.offset, self.limits)
        if problem:
            raise SceneError([{"path": path, "message": problem}])
        lin = load_image(file, path, self.asset_dir, max_pixels=width * height)  # the file cannot have grown since
        h, w = lin.shape[:2]
        self.index[file] = len(self.info)
        self.info.append((self.offset, w, h))
        self.pixels.append(lin.reshape(-1, 3))
        self.offset += w * h
        return self.index[file]


def _material(m, path: str, images: _Images | None) -> MaterialData:
    d = MaterialData()
    d.kd = vec3(m.kd)
    d.ka_is_kd = 1 if m.ka is None else 0
    d.ka = vec3(m.ka if m.ka is not None else m.kd)
    d.ks = vec3(m.ks)
    d.shininess = float(m.shininess)
    d.kr = vec3(m.kr)
    d.kt = vec3(m.kt)
    d.ior = float(m.ior)
    d.fresnel = 1 if m.fresnel else 0
    d.gloss = float(m.gloss) if m.gloss is not None else 0.0
    d.emission = vec3(m.emission)
    d.tex, d.tex_size, d.tex_image = int(Texture.NONE), 1.0, 0
    d.tex_c1, d.tex_c2, d.tex_scale = wp.vec3(0.0), wp.vec3(0.0), wp.vec2(1.0, 1.0)
    if m.texture is not None and m.texture.type == "checker":
        d.tex, d.tex_size = int(Texture.CHECKER), float(m.texture.size)
        d.tex_c1, d.tex_c2 = vec3(m.texture.color1), vec3(m.texture.color2)
    elif m.texture is not None:
        assert images is not None, "an image texture needs the scene's images (only a light's material has none)"
        d.tex = int(Texture.IMAGE)
        d.tex_image = images.add(m.texture.file, f"{path}.texture.file")
        d.tex_scale = wp.vec2(*(float(s) for s in m.texture.scale))
    d.bump, d.bump_scale, d.bump_strength, d.bump_image = int(Bump.NONE), 1.0, 0.0, 0
    d.bump_uvscale = wp.vec2(1.0, 1.0)
    if m.bump is not None and m.bump.type == "noise":
        d.bump, d.bump_scale, d.bump_strength = int(Bump.NOISE), float(m.bump.scale), float(m.bump.strength)
    elif m.bump is not None:
        assert images is not None, "a bump map needs the scene's images (only a light's material has none)"
        d.bump, d.bump_strength = int(Bump.IMAGE), float(m.bump.strength)
        d.bump_image = images.add(m.bump.file, f"{path}.bump.file")
        d.bump_uvscale = wp.vec2(*(float(s) for s in m.bump.scale))
    return d


def _light_material(light) -> MaterialData:
    """Area lights are visible: radiance on the emitting side, black on the back, nothing else."""
    return _material(Material(kd=(0.0, 0.0, 0.0), ka=(0.0, 0.0, 0.0), emission=light.radiance), "", None)


def _camera(scene: Scene) -> CameraData:
    c = scene.camera
    cam = CameraData()
    lookfrom, lookat = np.asarray(c.lookfrom, float), np.asarray(c.lookat, float)
    forward = unit(lookat - lookfrom)
    right = unit(np.cross(forward, c.vup))
    up = np.cross(right, forward)
    cam.origin, cam.forward, cam.right, cam.up = vec3(lookfrom), vec3(forward), vec3(right), vec3(up)
    cam.h = math.tan(math.radians(c.vfov) / 2)
    cam.aspect = scene.film.width / scene.film.height
    cam.lens_radius = float(c.lens_radius)
    cam.focus_distance = float(c.focus_distance) if c.focus_distance else float(np.linalg.norm(lookat - lookfrom))
    cam.t0, cam.t1 = float(c.shutter[0]), float(c.shutter[1])
    cam.instants = int(c.instants or 0)
    return cam


def compile_scene(
    scene: Scene, asset_dir: Path = ASSET_DIR, device: str = "cpu", limits: Limits | None = None
) -> CompiledScene:
    """Flatten a validated scene into a SceneData on `device`. Raises SceneError on missing assets, and on
    images past `limits` (the library's defaults when None), found from their headers before any is decoded.
    The kernels bound each pixel sample's ray tree by `limits.max_tree_rays`.

    Flattening only: a radiosity scene's solution is solved by `tracer.radiosity.attach`, which
    render() runs as a phase with progress and ray_tree() runs when it needs it.

    The steps: the scene's materials, its objects (shapes and triangle groups), its lights (an area light
    also a shape), the shapes put in the kernels' order; then the Warp arrays: shapes, triangles,
    materials, lights and textures, and the scalars of the render's settings."""
    flat = _Flat(_Images(Path(asset_dir), limits or Limits()))
    flat.add_materials(scene)
    flat.add_objects(scene, Path(asset_dir))
    flat.add_lights(scene)
    flat.quads_first()
    data = SceneData()
    data.camera = _camera(scene)
    _fill_shapes(data, flat, device)
    keep, ntri = _compile_triangles(data, flat.groups, device)
    _fill_materials_lights(data, flat, device)
    _fill_textures(data, flat.images, device)
    _fill_settings(data, scene, flat.images.limits, device)
    return CompiledScene(
        scene=scene,
        data=data,
        object_names=[o.name for o in scene.objects],
        material_names=flat.mat_names,
        num_triangles=ntri,
        num_shapes=data.num_shapes,
        keep=keep,
        limits=flat.images.limits,
    )


@dataclass
class _Flat:
    """What compile_scene gathers before any Warp array is made: materials (the scene's named ones, then
    each inline one and each area light's, as met), shapes, triangle groups, and lights."""

    images: _Images
    mats: list[MaterialData] = field(default_factory=list)
    mat_names: list[str] = field(default_factory=list)
    mat_index: dict[str, int] = field(default_factory=dict)  # a named material's index in `mats`
    shapes: list[ShapeData] = field(default_factory=list)
    # triangle groups: 0 = every static triangle; then one group per moving object (own BVH, own velocity)
    groups: list[dict] = field(default_factory=lambda: [{"velocity": (0.0, 0.0, 0.0), "parts": []}])
    lights: list[LightData] = field(default_factory=list)

    def add_materials(self, scene: Scene) -> None:
        """The scene's named materials, in their order."""
        self.mat_names = list(scene.materials)
        self.mat_index = {n: i for i, n in enumerate(self.mat_names)}
        self.mats = [_material(m, json_path(("materials", n)), self.images) for n, m in scene.materials.items()]

    def material_of(self, i: int, obj) -> int:
        """Object i's material: a named one's index, or its inline material added."""
        if isinstance(obj.material, str):
            return self.mat_index[obj.material]
        self.mats.append(_material(obj.material, f"objects[{i}].material", self.images))
        self.mat_names.append(f"objects[{i}].material")
        return len(self.mats) - 1

    def shape(self, kind, i, m, p0=(0, 0, 0), p1=(0, 0, 0), p2=(0, 0, 0), radius=0.0, velocity=(0, 0, 0), light=-1,
              xf=None) -> None:  # fmt: skip
        """One analytic shape of object i (-1 - k for light k) with material m; a quad's plane normal and
        edge coordinates' vectors precomputed."""
        s = ShapeData()
        s.xf = wp.mat33(*np.asarray(np.eye(3) if xf is None else xf, dtype=np.float64).reshape(-1).tolist())
        s.kind, s.obj, s.mat, s.light = int(kind), i, m, light
        s.p0, s.p1, s.p2, s.radius, s.velocity = vec3(p0), vec3(p1), vec3(p2), float(radius), vec3(velocity)
        m = np.cross(p1, p2) if kind == Shape.QUAD else np.zeros(3)
        w = m / max(float(np.dot(m, m)), 1e-300)
        s.n, s.w, s.w2 = vec3(m / max(float(np.linalg.norm(m)), 1e-300)), vec3(np.cross(p2, w)), vec3(np.cross(w, p1))
        self.shapes.append(s)

    def triangles(self, i, m, v, f, velocity, uv=None, smooth=False) -> None:
        """Object i's triangles: into the static group, or a group of their own when they move."""
        part = (i, m, np.asarray(v, np.float64), np.asarray(f, np.int64), uv, smooth)
        if any(c != 0 for c in velocity):
            self.groups.append({"velocity": tuple(velocity), "parts": [part]})
        else:
            self.groups[0]["parts"].append(part)

    def add_objects(self, scene: Scene, asset_dir: Path) -> None:
        """Every object: an analytic shape, or triangles (a mesh file read from `asset_dir`)."""
        for i, obj in enumerate(scene.objects):
            m = self.material_of(i, obj)
            vel = obj.velocity
            if obj.type == "sphere":
                self.shape(Shape.SPHERE, i, m, p0=obj.center, radius=obj.radius, velocity=vel)
            elif obj.type == "plane":
                self.shape(Shape.PLANE, i, m, p0=obj.point, p1=unit(obj.normal), velocity=vel)
            elif obj.type == "quad":
                self.shape(Shape.QUAD, i, m, p0=obj.corner, p1=obj.edge1, p2=obj.edge2, velocity=vel)
            elif obj.type == "disk":
                self.shape(Shape.DISK, i, m, p0=obj.center, p1=unit(obj.normal), radius=obj.radius, velocity=vel)
            elif obj.type == "box":  # one slab test in the box's own coordinates
                fwd = transform_matrix(obj.transform)
                inv = np.linalg.inv(fwd[:3, :3])
                self.shape(Shape.BOX, i, m, p0=obj.min, p1=obj.max, p2=-inv @ fwd[:3, 3], velocity=vel, xf=inv)
            elif obj.type == "triangle":
                self.triangles(i, m, obj.vertices, [[0, 1, 2]], vel)
            elif obj.type == "mesh":
                if obj.file is not None:
                    v, f, uv = load_mesh_file(obj.file, f"objects[{i}].file", asset_dir)
                else:
                    v, f, uv = np.asarray(obj.vertices, float), np.asarray(obj.faces, np.int64), None
                self.triangles(i, m, _apply(transform_matrix(obj.transform), v), f, vel, uv, obj.smooth)

    def add_lights(self, scene: Scene) -> None:
        """Every light's LightData; an area light is visible too: a shape of its own, emitting its radiance."""
        for k, light in enumerate(scene.lights):
            self.lights.append(light_data(light))
            if isinstance(light, AREA_LIGHTS):
                self.mats.append(_light_material(light))
                self.mat_names.append(f"lights[{k}]")
                kind, where = light_shape(light)
                self.shape(kind, -1 - k, len(self.mats) - 1, light=k, **where)
                self.lights[-1].shape = len(self.shapes) - 1

    def quads_first(self) -> None:
        """Quads first (their own loop in the intersection tests, without the dispatch over kinds), the rest
        in the scene's order; an area light's shape index follows its shape."""
        order = sorted(range(len(self.shapes)), key=lambda k: self.shapes[k].kind != int(Shape.QUAD))
        where = {old: new for new, old in enumerate(order)}
        self.shapes = [self.shapes[k] for k in order]
        for ld in self.lights:
            if ld.shape >= 0:
                ld.shape = where[ld.shape]


def _fill_shapes(data: SceneData, flat: _Flat, device: str) -> None:
    """The analytic shapes' array and counts (one placeholder sphere when there are none)."""
    shapes = flat.shapes
    data.num_shapes = len(shapes)
    data.num_quads = sum(1 for s in shapes if s.kind == int(Shape.QUAD))
    data.shapes_move = int(any(s.velocity[0] != 0 or s.velocity[1] != 0 or s.velocity[2] != 0 for s in shapes))
    if not shapes:  # kernels index nothing when num_shapes == 0, but the array must exist
        flat.shape(Shape.SPHERE, -1, 0, radius=1.0)
    data.shapes = wp.array(flat.shapes, dtype=ShapeData, device=device)


def _fill_materials_lights(data: SceneData, flat: _Flat, device: str) -> None:
    """The materials' and lights' arrays (a default entry in an empty one: the array must exist)."""
    if not flat.mats:
        flat.mats.append(MaterialData())
    data.materials = wp.array(flat.mats, dtype=MaterialData, device=device)
    data.num_lights = len(flat.lights)
    data.lights = wp.array(flat.lights or [LightData()], dtype=LightData, device=device)


def _fill_textures(data: SceneData, images: _Images, device: str) -> None:
    """Every texture image's linear RGB in one array, and each one's (offset, width, height)."""
    if images.pixels:
        pixels = images.pixels[0] if len(images.pixels) == 1 else np.concatenate(images.pixels)
        data.tex_pixels = wp.array(pixels, dtype=wp.vec3, device=device)
        data.tex_info = wp.array(np.array(images.info, dtype=np.int32), dtype=wp.vec3i, device=device)
    else:
        data.tex_pixels = wp.zeros(1, dtype=wp.vec3, device=device)
        data.tex_info = wp.zeros(1, dtype=wp.vec3i, device=device)


def _fill_settings(data: SceneData, scene: Scene, limits: Limits, device: str) -> None:
    """The scalars: background, ambient and fog; the integrator and its bounds; the film, the sampler and
    the reconstruction filter's tables; the seed; no radiosity solution yet."""
    data.background, data.ambient = vec3(scene.background), vec3(scene.ambient)
    data.fog_density, data.fog_color = float(scene.fog.density), vec3(scene.fog.color)
    r = scene.render
    data.integrator = int(Integrator[r.integrator.upper()])
    data.max_depth, data.min_weight, data.light_samples = int(r.max_depth), float(r.min_weight), int(r.light_samples)
    data.max_tree_rays = int(limits.max_tree_rays)
    data.width, data.height = int(scene.film.width), int(scene.film.height)
    sm = scene.sampler
    assert sm.spp is not None, "the Sampler's validator fills in its type's default spp"
    data.spp, data.sampler = int(sm.spp), int(SamplerKind[sm.type.upper()])
    data.threshold, data.max_level, data.jitter = float(sm.threshold), int(sm.max_level), int(sm.jitter)
    flt = scene.film.filter
    assert flt.radius is not None, "the Filter's validator fills in its type's default radius"
    data.filter, data.filter_radius = int(FilterKind[flt.type.upper()]), float(flt.radius)
    icdf, sign, norm = filter_tables(flt.type, float(flt.radius))
    data.filter_icdf = wp.array(icdf, dtype=float, device=device)
    data.filter_sign = wp.array(sign, dtype=float, device=device)
    data.filter_norm = norm
    data.seed = int(r.seed)
    data.rad = inactive_radiosity(device)


def _compile_triangles(data: SceneData, groups: list[dict], device: str) -> tuple[list, int]:
    """Every triangle into global shading arrays, and one wp.Mesh (BVH) per group."""
    pts, idx, nrm, uvs, fobj, fmat, fflag = [], [], [], [], [], [], []
    meshes, vels, face0, keep = [], [], [], []
    nverts = nfaces = 0
    for g in groups:
        if not g["parts"]:
            continue
        gpts, gidx = [], []
        gverts = 0
        for i, m, v, f, uv, smooth in g["parts"]:
            gpts.append(v)
            gidx.append(f + gverts)
            gverts += len(v)
            pts.append(v)
            idx.append(f + nverts)
            nverts += len(v)
            nrm.append(vertex_normals(v, f))
            uvs.append(uv if uv is not None else np.zeros((len(v), 2)))
            fobj.append(np.full(len(f), i))
            fmat.append(np.full(len(f), m))
            fflag.append(np.full(len(f), (FACE_SMOOTH if smooth else 0) | (FACE_UV if uv is not None else 0)))
        gp = wp.array(np.concatenate(gpts).astype(np.float32), dtype=wp.vec3, device=device)
        gi = wp.array(np.concatenate(gidx).reshape(-1).astype(np.int32), dtype=wp.int32, device=device)
        mesh = wp.Mesh(points=gp, indices=gi, bvh_constructor="sah")
        keep += [mesh, gp, gi]
        meshes.append(mesh.id)
        vels.append(g["velocity"])
        face0.append(nfaces)
        nfaces += sum(len(f) for _, _, _, f, _, _ in g["parts"])
    data.num_meshes = len(meshes)
    if meshes:
        data.mesh_points = wp.array(np.concatenate(pts).astype(np.float32), dtype=wp.vec3, device=device)
        data.mesh_indices = wp.array(np.concatenate(idx).reshape(-1).astype(np.int32), dtype=wp.int32, device=device)
        data.mesh_normals = wp.array(np.concatenate(nrm).astype(np.float32), dtype=wp.vec3, device=device)
        data.mesh_uvs = wp.array(np.concatenate(uvs).astype(np.float32), dtype=wp.vec2, device=device)
        data.face_obj = wp.array(np.concatenate(fobj).astype(np.int32), dtype=wp.int32, device=device)
        data.face_mat = wp.array(np.concatenate(fmat).astype(np.int32), dtype=wp.int32, device=device)
        data.face_flags = wp.array(np.concatenate(fflag).astype(np.int32), dtype=wp.int32, device=device)
        data.meshes = wp.array(np.array(meshes, dtype=np.uint64), dtype=wp.uint64, device=device)
        data.mesh_vel = wp.array(np.array(vels, dtype=np.float32), dtype=wp.vec3, device=device)
        data.mesh_face0 = wp.array(np.array(face0, dtype=np.int32), dtype=wp.int32, device=device)
    else:
        for name, dt in (
            ("mesh_points", wp.vec3),
            ("mesh_normals", wp.vec3),
            ("mesh_uvs", wp.vec2),
            ("mesh_indices", wp.int32),
            ("face_obj", wp.int32),
            ("face_mat", wp.int32),
            ("face_flags", wp.int32),
            ("meshes", wp.uint64),
            ("mesh_vel", wp.vec3),
            ("mesh_face0", wp.int32),
        ):
            setattr(data, name, wp.zeros(3, dtype=dt, device=device))
    return keep, nfaces
