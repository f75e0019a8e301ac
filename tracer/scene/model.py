"""The Scene, the root of the format, and its checks across the whole scene: every material defined,
the primitives (mesh files included), all of its images together, and a radiosity solve's patches and
rays, each against its limit (tracer/limits.py) and reported at its own JSON path."""

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, ValidationInfo

from tracer import meshing
from tracer.assets import AssetError, read_mesh
from tracer.errors import show_value
from tracer.scene.base import _has, _Model
from tracer.scene.camera import Camera, Film, Sampler
from tracer.scene.context import _asset_dir, _image_size, _limits, texture_problem
from tracer.scene.lights import Light
from tracer.scene.materials import ImageBump, ImageTexture, Material, _unknown_material
from tracer.scene.objects import Mesh, Object, _Object, primitive_count
from tracer.scene.render import Fog, RenderSettings
from tracer.scene.values import RGB, Str, _error, _is_number


def _file_triangles(objects: list, info: ValidationInfo) -> dict[int, int]:
    """Object index -> triangles of its mesh file, when validation resolves assets (read once: cached)."""
    folder, out = _asset_dir(info), {}
    if folder is None:
        return out
    for i, o in enumerate(objects):
        if isinstance(o, Mesh) and o.file is not None:
            try:
                out[i] = len(read_mesh(o.file, folder, _limits(info).max_primitives)[1])
            except AssetError:  # reported at objects[i].file
                pass
    return out


def image_files(materials: dict, objects: list) -> list[tuple[tuple, str]]:
    """(location, file) of every image texture and bump of a scene, in the order the renderer loads them:
    the named materials', then the objects' own (tracer/kernels/compile.py). A location names the tags of the
    unions it passes (an object's type, an inline material, an image), as pydantic's own do."""
    found = [(("materials", name), m) for name, m in materials.items()]
    found += [
        (("objects", i, o.type, "material", "inline"), o.material)
        for i, o in enumerate(objects)
        if isinstance(o.material, Material)
    ]
    return [
        ((*at, kind, "image", "file"), part.file)
        for at, m in found
        for kind in ("texture", "bump")
        if isinstance(part := getattr(m, kind), ImageTexture | ImageBump)
    ]


def _texture_total(files: list[tuple[tuple, str]], info: ValidationInfo) -> list[tuple[tuple, str]]:
    """The scene's images against the total: each distinct file counted once, from its header (an image that
    cannot be read, or is past the limit of one image, is reported at its own field and not counted)."""
    limits, used, seen = _limits(info), 0, set()
    for loc, file in files:
        if file in seen:
            continue
        seen.add(file)
        try:
            width, height = _image_size(file, info)
        except AssetError:
            continue
        if width * height > limits.max_texture_pixels:
            continue
        problem = texture_problem(width, height, used, limits)
        if problem:
            return [(loc, problem)]
        used += width * height
    return []


def _solve_limits(v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
    """A radiosity scene's solve against the limits on its patches and rays, counted from the geometry (mesh
    files included when validation resolves assets) before anything is meshed."""
    triangles = meshing.mesh_triangles(v.objects, meshing.mesh_files(_asset_dir(info), _limits(info).max_primitives))
    problems = meshing.solve_problems(v, triangles, v.render.radiosity, _limits(info))
    return [(("render", "radiosity", field), message) for field, message in problems]


def _version(v: Any) -> Any:
    if _is_number(v) and v == 1:
        return 1
    raise _error(f"unsupported scene version {show_value(v)}; this tracer reads version 1")


class Scene(_Model):
    """A scene, format version 1 (docs/scene-format.md)."""

    version: Annotated[Literal[1], BeforeValidator(_version)] = Field(1, description="Scene format version.")
    name: Str | None = Field(None, description="Free text: the scene's title.")
    description: Str | None = Field(None, description="Free text: what the scene shows (an addition to v1).")
    camera: Camera = Field(description="The camera.")
    film: Film = Field(default_factory=Film, description="Image size, filter, exposure.")
    sampler: Sampler = Field(default_factory=Sampler, description="Pixel sampling.")
    render: RenderSettings = Field(default_factory=RenderSettings, description="Integrator and ray-tree limits.")
    background: RGB = Field((0.0, 0.0, 0.0), description="Radiance of rays that leave the scene.")
    ambient: RGB = Field((0.0, 0.0, 0.0), description="Ambient light I_a of the ka term (whitted only).")
    fog: Fog = Field(default_factory=Fog, description="Homogeneous fog.")
    materials: dict[str, Material] = Field(default_factory=dict, description="Named materials.")
    lights: list[Light] = Field(default_factory=list, description="Light sources.")
    objects: list[Object] = Field(default_factory=list, description="Surfaces.")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if not _has(v, "objects"):
            return []
        errors = []
        if _has(v, "materials"):
            errors += [
                (("objects", i, "material"), _unknown_material(o.material, v.materials))
                for i, o in enumerate(v.objects)
                if isinstance(o.material, str) and o.material not in v.materials
            ]
        limits = _limits(info)
        files = _file_triangles(v.objects, info)
        count = primitive_count(v.objects) + sum(files.values())
        if count > limits.max_primitives:
            biggest = sorted(files.items(), key=lambda item: -item[1])[:3]
            where = ", ".join(f"objects[{i}].file: {n} triangles" for i, n in biggest)
            where = f" ({where})" if where else ""
            errors.append((("objects",), f"{count} primitives{where}; {limits.at_most('max_primitives')}"))
        if _asset_dir(info) is not None:
            errors += _texture_total(image_files(v.materials if _has(v, "materials") else {}, v.objects), info)
        if _has(v, "render", "camera", "lights") and v.render.integrator_info.prepass == "radiosity":
            errors += _solve_limits(v, info)
        return errors

    def material_for(self, obj: _Object) -> Material:
        """The object's material: its inline one, or the named one from `materials`."""
        return obj.material if isinstance(obj.material, Material) else self.materials[obj.material]
