"""Scene format version 1: pydantic models, loading, validation and the JSON Schema.

The format is described in docs/scene-format.md; the models are its executable form, and every field's
description (meaning and unit) is published in the JSON Schema the web editor uses. One module per concept:

    values.py     value types: strict finite numbers inside float32's range, points, vectors, colours
    context.py    what validation is given: the limits (tracer/limits.py) and the asset folder's files
    base.py       the base model: unknown keys are errors, every independent error at once
    camera.py     the camera, the film and its filter, the pixel sampler
    render.py     the integrator and its ray tree's limits, the radiosity settings, the fog
    materials.py  Phong materials, textures, bump maps, an object's material by name or inline
    lights.py     point, directional and spot lights; the area lights (quad, disk, sphere)
    objects.py    the surfaces, and the primitives the renderer will build of them
    model.py      the Scene, and its checks across the whole scene
    lint.py       warnings: settings that have no effect
    load.py       load_scene, validate_scene, scene_json_schema

Validation works in three steps, each reporting at the offending field's own JSON path:

1. the models: types, ranges (numbers finite and inside float32's), unknown keys
   (`extra="forbid"`), and checks between fields of one model (`_checks`: degenerate quads,
   lookfrom == lookat, ...) at explicit locations. Those checks run even when other fields of
   the model failed, on the fields that are valid, so every independent error comes at once;
2. `tracer.errors.pydantic_errors`: pydantic's error location -> JSON path (`objects[3].radius`, union
   tags dropped) and pydantic's message -> a human one ("unknown field 'radus'; did you mean 'radius'?");
3. `lint._warnings`: settings that have no effect, found from `model_fields_set`.

The limits (`Limits`, made from the one table of tracer/limits.py), the set of material names and,
when asked (`load_scene(..., assets=DIR)`), the asset folder reach the validators through pydantic's
validation context: an undefined material is reported even when other parts are invalid, and the asset
files (tracer/assets.py) are resolved and read as part of validation, their errors at their own paths too.

Every name is re-exported here (`from tracer.scene import Scene, load_scene`); ASSET_DIR, resolve_asset,
json_path and SceneError have been tracer.scene's since v1.
"""

from tracer.assets import ASSET_DIR, resolve_asset
from tracer.errors import SceneError, json_path
from tracer.limits import Limits
from tracer.scene.camera import FILTER_RADIUS, Camera, Film, Filter, Sampler, SamplerType
from tracer.scene.context import AssetFile, ImageFile, MeshFile, texture_problem
from tracer.scene.lights import (
    AREA_LIGHT_TYPES,
    AREA_LIGHTS,
    LIGHT_TYPES,
    DirectionalLight,
    DiskLight,
    Light,
    PointLight,
    QuadLight,
    SphereLight,
    SpotLight,
)
from tracer.scene.load import load_scene, scene_json_schema, validate_scene
from tracer.scene.materials import (
    Bump,
    CheckerTexture,
    ImageBump,
    ImageTexture,
    Material,
    MaterialRef,
    NoiseBump,
    Texture,
)
from tracer.scene.model import Scene, image_files
from tracer.scene.objects import (
    Box,
    Disk,
    Mesh,
    Object,
    Plane,
    Quad,
    Sphere,
    Transform,
    Triangle,
    _Object,
    primitive_count,
)
from tracer.scene.render import Fog, IntegratorName, RadiositySettings, RenderSettings
from tracer.scene.values import (
    F32,
    RGB,
    Attenuation,
    Bool,
    Dir3,
    Face,
    Int,
    NonNeg,
    NonZero,
    Num,
    Pair,
    Positive,
    Scale3,
    Str,
    Vec3,
)

__all__ = [
    "AREA_LIGHTS",
    "AREA_LIGHT_TYPES",
    "ASSET_DIR",
    "AssetFile",
    "Attenuation",
    "Bool",
    "Box",
    "Bump",
    "Camera",
    "CheckerTexture",
    "Dir3",
    "DirectionalLight",
    "Disk",
    "DiskLight",
    "F32",
    "FILTER_RADIUS",
    "Face",
    "Film",
    "Filter",
    "Fog",
    "ImageBump",
    "ImageFile",
    "ImageTexture",
    "Int",
    "IntegratorName",
    "LIGHT_TYPES",
    "Light",
    "Limits",
    "Material",
    "MaterialRef",
    "Mesh",
    "MeshFile",
    "NoiseBump",
    "NonNeg",
    "NonZero",
    "Num",
    "Object",
    "Pair",
    "Plane",
    "PointLight",
    "Positive",
    "Quad",
    "QuadLight",
    "RGB",
    "RadiositySettings",
    "RenderSettings",
    "Sampler",
    "SamplerType",
    "Scale3",
    "Scene",
    "SceneError",
    "Sphere",
    "SphereLight",
    "SpotLight",
    "Str",
    "Texture",
    "Transform",
    "Triangle",
    "Vec3",
    "_Object",
    "image_files",
    "json_path",
    "load_scene",
    "primitive_count",
    "resolve_asset",
    "scene_json_schema",
    "texture_problem",
    "validate_scene",
]
