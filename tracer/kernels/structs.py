"""The data the kernels share: one ``@wp.struct`` per concept, and ``SceneData`` holding them all.

These are the interfaces between the modules (as pbrt-v4 keeps its interfaces apart from their
implementations): tracer/kernels/compile.py fills them from the scene's models, and the @wp.func code of
geometry, lights, materials, sampling, camera, the integrators and the radiosity solver reads them.
This module imports nothing of the renderer but its named kinds' Warp initialisation, so every other
module can import it.

Warp passes a struct to a @wp.func by value: a SceneData is about 1.7 KB, so the helpers that take one
are inlined (``@wp.func(inline=True)``), or each call would copy it (BENCHMARKS.md, "Whitted kernel").
"""

from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import warp as wp

from tracer.kernels import wpinit  # noqa: F401  (initialise Warp once)

if TYPE_CHECKING:
    _C = TypeVar("_C", bound=type)

    def struct(c: _C) -> _C:
        """What pyright sees of `wp.struct`: the class itself, so its fields are typed attributes and its
        name a type (Warp's own annotation returns a `Struct` object, which is not a class)."""
        ...

    def empty(shape: int | tuple[int, ...], dtype: Any, device: str = "cpu") -> wp.array:
        """What pyright sees of `wp.empty`: any Warp type as the dtype (Warp leaves that parameter
        unannotated, so pyright takes its default, float, for its type)."""
        ...

else:
    struct = wp.struct  # at run time Warp's decorator itself: the structs and kernels are Warp's, unchanged
    empty = wp.empty


@struct
class CameraData:
    origin: wp.vec3  # lookfrom
    forward: wp.vec3  # unit vector towards lookat
    right: wp.vec3  # unit, forward x vup
    up: wp.vec3  # unit, right x forward
    h: float  # tan(vfov / 2)
    aspect: float  # width / height
    lens_radius: float  # thin-lens aperture radius, world units (0 = pinhole)
    focus_distance: float  # distance to the focal plane along forward
    t0: float  # shutter open time
    t1: float  # shutter close time
    instants: int  # 0: continuous time per ray; N: sample s at instant (s mod N + 0.5) / N of the shutter


@struct
class ShapeData:
    kind: int  # SHAPE_*
    obj: int  # index into scene.objects (the ray tree reports it); -1 - k for area light k
    mat: int  # index into SceneData.materials
    p0: wp.vec3  # sphere/disk centre, plane point, quad corner
    p1: wp.vec3  # plane/disk normal (unit), quad edge1
    p2: wp.vec3  # quad edge2
    n: wp.vec3  # quad: the unit normal, along edge1 x edge2
    w: wp.vec3  # quad: with m = edge1 x edge2, edge2 x m / |m|^2: a hit's edge1 coordinate is w . (p - corner)
    w2: wp.vec3  # quad: m x edge1 / |m|^2, its edge2 coordinate w2 . (p - corner)
    xf: wp.mat33  # box: world -> box coordinates, local = xf world + p2 (p0, p1 = the box's min and max)
    radius: float  # sphere/disk radius
    velocity: wp.vec3  # world units per unit time (motion blur)
    light: int  # index of the area light this shape is, or -1


@struct
class MaterialData:
    kd: wp.vec3  # diffuse reflectance
    ka: wp.vec3  # ambient coefficient (used when ka_is_kd == 0)
    ka_is_kd: int  # 1: ka = kd after texturing
    ks: wp.vec3  # Phong specular coefficient
    shininess: float  # Phong exponent n
    kr: wp.vec3  # reflection-ray weight
    kt: wp.vec3  # transmission-ray weight
    ior: float  # index of refraction inside
    fresnel: int  # 1: scale kr, kt by exact dielectric Fresnel R, 1 - R
    gloss: float  # cos^m lobe exponent; 0 = perfect mirror
    emission: wp.vec3  # emitted radiance (front face)
    tex: int  # TEX_*
    tex_size: float  # checker cell size, world units
    tex_c1: wp.vec3  # checker colour where the cell parity is even
    tex_c2: wp.vec3  # checker colour where it is odd
    tex_image: int  # index into tex_info
    tex_scale: wp.vec2  # uv scale of an image texture
    bump: int  # BUMP_*
    bump_scale: float  # noise frequency (cells per world unit)
    bump_strength: float  # height scale h
    bump_image: int  # index into tex_info
    bump_uvscale: wp.vec2  # uv scale of an image bump map


@struct
class LightData:
    kind: int  # LightKind (tracer/kernels/lights.py)
    position: wp.vec3  # point/spot position
    direction: wp.vec3  # directional: the way light travels; spot: the axis (unit)
    intensity: wp.vec3  # W/sr (point, spot) or W/m^2 irradiance (directional)
    attenuation: wp.vec3  # c1, c2, c3 of f_att = 1 / (c1 + c2 d + c3 d^2)
    cos_cutoff: float  # spot: cosine of the cone half-angle
    falloff: float  # spot: exponent of cos(psi)
    edge1: wp.vec3  # quad light: corner = position, edges edge1 and edge2; disk: normal = direction
    edge2: wp.vec3
    radius: float  # disk and sphere lights
    area: float  # emitting area, world units^2
    shape: int  # index of an area light's own shape in SceneData.shapes, else -1


@struct
class PatchIndex:
    """Which radiosity patch a point of a surface lies on (tracer/radiosity/lookup.py, `patch_at`): every patch
    as triangles of one wp.Mesh, and how each object's points are brought onto its facets."""

    mesh: wp.uint64  # every patch as triangles (a parallelogram is two)
    tri_patch: wp.array(dtype=wp.int32)  # triangle -> front patch index; its back side is + n
    tri_obj: wp.array(dtype=wp.int32)  # triangle -> object index (a point must be on the same object)
    obj_kind: wp.array(dtype=wp.int32)  # per object, PATCHES_*: how its points find their facet
    obj_center: wp.array(dtype=wp.vec3)  # per object: a sphere's or a disk's centre (at time 0)
    obj_radius: wp.array(dtype=float)  # sphere: its radius; disk: the circle inside its facets' polygon
    n: int  # patches per side
    max_dist: float  # how far from a facet a point of a flat surface may be to belong to it


@struct
class RadiosityData:
    """A radiosity solution for the `radiosity` integrator (`radiosity.attach` fills it); inactive otherwise."""

    active: int  # 1 when the scene's integrator is radiosity
    mode: int  # RAD_TWO_PASS: the ray tree + the solution's interreflection; RAD_FLAT: patches; RAD_SMOOTH
    index: PatchIndex  # the patch under a hit
    radiosity: wp.array(dtype=wp.vec3)  # (2n) B, exitance W/m^2 (radiance B / pi)
    indirect: wp.array(dtype=wp.vec3)  # (2n) B less the emitted and the directly lit part
    rho: wp.array(dtype=wp.vec3)  # (2n) the patch's reflectance
    corners: wp.array(dtype=wp.vec3)  # (2 x 3 per triangle) B at the triangle's corners: front, then back
    corners_ind: wp.array(dtype=wp.vec3)  # the same for the interreflected part (two-pass shading)


@struct
class SceneData:
    camera: CameraData
    shapes: wp.array(dtype=ShapeData)
    num_shapes: int
    num_quads: int  # shapes[0 .. num_quads - 1] are the quads (parallelograms), the rest other kinds
    shapes_move: int  # 1 when some shape has a velocity (else the intersection loops skip the motion)
    meshes: wp.array(dtype=wp.uint64)  # wp.Mesh ids: group 0 the static triangles, then one per moving object
    mesh_vel: wp.array(dtype=wp.vec3)  # velocity of each group
    mesh_face0: wp.array(dtype=wp.int32)  # global index of each group's first face
    num_meshes: int
    mesh_points: wp.array(dtype=wp.vec3)
    mesh_indices: wp.array(dtype=wp.int32)  # 3 per face
    mesh_normals: wp.array(dtype=wp.vec3)  # per vertex, for smooth shading
    mesh_uvs: wp.array(dtype=wp.vec2)  # per vertex
    face_obj: wp.array(dtype=wp.int32)  # object index of each face
    face_mat: wp.array(dtype=wp.int32)  # material index of each face
    face_flags: wp.array(dtype=wp.int32)  # bit 0: smooth normals, bit 1: vertex uvs
    materials: wp.array(dtype=MaterialData)
    lights: wp.array(dtype=LightData)
    num_lights: int
    tex_pixels: wp.array(dtype=wp.vec3)  # all texture images, linear RGB, row-major, top row first
    tex_info: wp.array(dtype=wp.vec3i)  # offset, width, height of each image
    background: wp.vec3  # radiance of rays that leave the scene
    ambient: wp.vec3  # I_a
    fog_density: float  # per world unit; 0 = no fog
    fog_color: wp.vec3
    integrator: int  # Integrator (tracer/kernels/kinds.py)
    max_depth: int  # bounces; 1 = ray casting
    min_weight: float
    max_tree_rays: int  # eye, reflection and transmission rays of one pixel sample's tree, at most (limits.py)
    light_samples: int
    width: int
    height: int
    spp: int
    sampler: int  # SAMPLER_*
    threshold: float  # adaptive: max colour difference of a uniform cell
    max_level: int  # adaptive: subdivision limit
    jitter: int  # adaptive: 1 = stochastic positions inside the cells
    filter: int  # FILTER_*
    filter_radius: float  # half-width in pixels
    filter_icdf: wp.array(dtype=float)  # inverse CDF of |f| in 1D: u in [0,1] -> offset in [-radius, radius]
    filter_sign: wp.array(dtype=float)  # sign of f at those offsets (Mitchell's negative lobes)
    filter_norm: float  # (integral |f| / integral f)^2: the weight of a positive sample
    seed: int
    rad: RadiosityData


FACE_SMOOTH = 1
FACE_UV = 2


def vec3(x) -> wp.vec3:
    """Three numbers (a model's tuple, a numpy row) as a wp.vec3."""
    return wp.vec3(float(x[0]), float(x[1]), float(x[2]))


def unit(x) -> np.ndarray:
    """x / |x| in float64 (the models' direction fields need not be normalised)."""
    a = np.asarray(x, dtype=np.float64)
    return a / np.linalg.norm(a)


def empty_patch_index(device: str = "cpu") -> PatchIndex:
    ix = PatchIndex()
    ix.mesh, ix.n, ix.max_dist = wp.uint64(0), 0, 0.0
    ix.tri_patch = wp.zeros(1, dtype=wp.int32, device=device)
    ix.tri_obj = wp.zeros(1, dtype=wp.int32, device=device)
    ix.obj_kind = wp.zeros(1, dtype=wp.int32, device=device)
    ix.obj_center = wp.zeros(1, dtype=wp.vec3, device=device)
    ix.obj_radius = wp.zeros(1, dtype=float, device=device)
    return ix


def inactive_radiosity(device: str = "cpu") -> RadiosityData:
    r = RadiosityData()
    r.active, r.mode = 0, 0
    r.index = empty_patch_index(device)
    for name in ("radiosity", "indirect", "rho", "corners", "corners_ind"):
        setattr(r, name, wp.zeros(1, dtype=wp.vec3, device=device))
    return r
