"""Scene format version 1: pydantic models, loading, validation and the JSON Schema.

The format is described in docs/scene-format.md; the models below are its executable form, and every field's
description (meaning and unit) is published in the JSON Schema the web editor uses.
Validation works in three steps, each reporting at the offending field's own JSON path:

1. the models: types, ranges (numbers finite and inside float32's), unknown keys
   (`extra="forbid"`), and checks between fields of one model (`_checks`: degenerate quads,
   lookfrom == lookat, ...) at explicit locations. Those checks run even when other fields of
   the model failed, on the fields that are valid, so every independent error comes at once;
2. `tracer.errors.pydantic_errors`: pydantic's error location -> JSON path (`objects[3].radius`, union
   tags dropped) and pydantic's message -> a human one ("unknown field 'radus'; did you mean 'radius'?");
3. `_warnings`: settings that have no effect, found from `model_fields_set`.

The limits (`Limits`, made from the one table of tracer/limits.py), the set of material names and,
when asked (`load_scene(..., assets=DIR)`), the asset folder reach the validators through pydantic's
validation context: an undefined material is reported even when other parts are invalid, and the asset
files (tracer/assets.py) are resolved and read as part of validation, their errors at their own paths too.
"""

import difflib
import functools
import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args

from annotated_types import Ge, Gt, Le
from pydantic import (
    AfterValidator,
    AllowInfNan,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Strict,
    Tag,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError
from pydantic_core.core_schema import ErrorType

from tracer import meshing
from tracer.assets import (  # noqa: F401 (ASSET_DIR and resolve_asset: re-exported, tracer.scene's since v1)
    ASSET_DIR,
    AssetError,
    image_size,
    path_problem,
    read_mesh,
    resolve_asset,
)
from tracer.errors import (  # noqa: F401 (json_path: re-exported, tracer.scene's since v1)
    FINITE,
    FLOAT32,
    FLOAT32_MAX,
    SceneError,
    json_path,
    pydantic_errors,
    show_value,
)
from tracer.integrators import BY_NAME, INTEGRATORS, IntegratorInfo
from tracer.integrators import NAMES as INTEGRATOR_NAMES
from tracer.limits import Limits

IntegratorName = Literal[INTEGRATOR_NAMES]  # "whitted", "path", ...: the table in tracer/integrators/__init__.py
SamplerType = Literal["center", "grid", "random", "jittered", "adaptive", "lowdiscrepancy"]


# ---------------------------------------------------------------------------------------------
# Value types. Numbers are strict (no "1.5" strings, no booleans) and finite.


def _error(message: str) -> PydanticCustomError:
    return PydanticCustomError("scene", "{message}", {"message": message})


def _raise_at(errors: list[tuple[tuple, str]]) -> None:
    """Raise errors at explicit locations relative to the model being validated."""
    if errors:
        details = [InitErrorDetails(type=_error(msg), loc=loc, input=None) for loc, msg in errors]
        raise ValidationError.from_exception_data("Scene", details)


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _finite(v: float) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # an int too large for a float
        return False


def _float32(v: Any) -> Any:
    """Before-validator: a finite number past float32's range is an error (NaN, Infinity: the type's)."""
    if _is_number(v) and _finite(v) and abs(v) > FLOAT32_MAX:
        raise _error(FLOAT32)
    return v


def _triple(expected: str, scalar=None):
    """Before-validator: accept a list of three (and, with `scalar`, one number -> scalar(v))."""

    def check(v: Any) -> Any:
        if isinstance(v, list | tuple) and len(v) == 3:
            return v
        if scalar is not None and _is_number(v):
            if not _finite(v):
                raise _error(FINITE)
            return scalar(_float32(v))
        raise _error(f"expected {expected}, got {show_value(v)}")

    return check


def _grey(v: float) -> tuple[float, float, float]:
    if v < 0:
        raise _error("must be >= 0")
    return (float(v),) * 3


def _uniform_scale(v: float) -> tuple[float, float, float]:
    if v == 0:
        raise _error("must not be zero")
    return (float(v),) * 3


def _nonzero(v: float) -> float:
    if v == 0:
        raise _error("must not be zero")
    return v


def _nonzero_length(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if _length(v) == 0:
        raise _error("must not be a zero-length vector")
    return v


def _not_all_zero(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if not any(v):
        raise _error("must not be all zero: f_att = 1 / (c1 + c2 d + c3 d^2)")
    return v


def _pair(v: Any) -> Any:
    if isinstance(v, list | tuple) and len(v) == 2:
        return v
    raise _error(f"expected a pair [a, b], got {show_value(v)}")


def _asset_dir(info: ValidationInfo) -> Path | None:
    """The asset folder to resolve files in, when validation is asked to (`load_scene(..., assets=DIR)`)."""
    return (info.context or {}).get("assets")


def _asset_file(v: str) -> str:
    """A file never reaches outside the asset folder (existence is checked by `resolve_asset`)."""
    problem = path_problem(v)
    if problem:
        raise _error(problem)
    return v


def _image_size(file: str, info: ValidationInfo) -> tuple[int, int]:
    """(width, height) of an image from its header, read once per validation (the scene's total reads it again)."""
    sizes = info.context.setdefault("image_sizes", {})
    if file not in sizes:
        try:
            sizes[file] = image_size(file, _asset_dir(info))
        except AssetError as e:
            sizes[file] = e
    if isinstance(sizes[file], AssetError):
        raise sizes[file]
    return sizes[file]


def _image_file(v: str, info: ValidationInfo) -> str:
    """With an asset folder: the image exists (or is a data: URI) and its header is readable; no pixels decoded."""
    if _asset_dir(info) is not None:
        try:
            width, height = _image_size(v, info)
        except AssetError as e:
            raise _error(e.message) from None
        problem = texture_problem(width, height, 0, _limits(info))
        if problem:
            raise _error(problem)
    return v


def texture_problem(width: int, height: int, used: int, limits: Limits) -> str | None:
    """What is wrong with one more image of width x height pixels when the scene's images before it hold
    `used` pixels (None: nothing). Validation and the renderer both ask, before any pixel is decoded."""
    pixels = width * height
    if pixels > limits.max_texture_pixels:
        return f"the image is {width}x{height} = {pixels} pixels; {limits.at_most('max_texture_pixels')}"
    if used + pixels > limits.max_texture_pixels_total:
        return (
            f"with this {width}x{height} image the scene's images come to {used + pixels} pixels; all of a "
            f"scene's images together {limits.at_most('max_texture_pixels_total')}"
        )
    return None


def _mesh_file(v: str, info: ValidationInfo) -> str:
    """With an asset folder: the mesh exists (or is a data: URI) and reads as triangles."""
    folder = _asset_dir(info)
    if folder is not None:
        try:
            read_mesh(v, folder)
        except AssetError as e:
            raise _error(e.message) from None
    return v


# Numbers are finite and inside float32's range, the renderer's. The components of vectors and colours
# (F32, NonNeg) have that range as bounds of their own check (no Python call per vertex). A scalar field
# may add bounds (Field(gt=0, le=180)), which an annotation's bounds would override: its number (Num,
# Positive) checks the range in a before-validator instead.
F32 = Annotated[float, Strict(), AllowInfNan(False), Ge(-FLOAT32_MAX), Le(FLOAT32_MAX)]
NonNeg = Annotated[float, Strict(), AllowInfNan(False), Ge(0), Le(FLOAT32_MAX)]
Num = Annotated[float, Strict(), AllowInfNan(False), BeforeValidator(_float32)]
Positive = Annotated[float, Strict(), AllowInfNan(False), Gt(0), BeforeValidator(_float32)]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Str = Annotated[str, Strict()]
Vec3 = Annotated[tuple[F32, F32, F32], BeforeValidator(_triple("a point [x, y, z]"))]
Dir3 = Annotated[tuple[F32, F32, F32], BeforeValidator(_triple("a vector [x, y, z]")), AfterValidator(_nonzero_length)]
RGB = Annotated[
    tuple[NonNeg, NonNeg, NonNeg],
    BeforeValidator(
        _triple("an RGB triple [r, g, b] or a single number", _grey),
        json_schema_input_type=Union[NonNeg, tuple[NonNeg, NonNeg, NonNeg]],  # noqa: UP007
    ),
]
Attenuation = Annotated[
    tuple[NonNeg, NonNeg, NonNeg], BeforeValidator(_triple("[c1, c2, c3]")), AfterValidator(_not_all_zero)
]
NonZero = Annotated[F32, AfterValidator(_nonzero)]
Scale3 = Annotated[
    tuple[NonZero, NonZero, NonZero],
    BeforeValidator(
        _triple("a scale factor or [sx, sy, sz]", _uniform_scale),
        json_schema_input_type=Union[Num, tuple[Num, Num, Num]],  # noqa: UP007
    ),
]
Pair = Annotated[tuple[F32, F32], BeforeValidator(_pair)]
Face = Annotated[tuple[Int, Int, Int], BeforeValidator(_triple("a face [i, j, k] of three vertex indices"))]
AssetFile = Annotated[Str, AfterValidator(_asset_file)]
ImageFile = Annotated[AssetFile, AfterValidator(_image_file)]
MeshFile = Annotated[AssetFile, AfterValidator(_mesh_file)]


def _length(v) -> float:
    return math.sqrt(sum(c * c for c in v))


def _sub(a, b) -> tuple[float, float, float]:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _parallel(a, b, eps: float = 1e-9) -> bool:
    """True when a and b are parallel (|a x b| tiny relative to |a| |b|)."""
    cross = (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
    return _length(cross) <= eps * _length(a) * _length(b)


def _limits(info: ValidationInfo) -> Limits:
    return (info.context or {}).get("limits") or Limits()


_KNOWN_ERRORS = frozenset(get_args(ErrorType))


def _details(err: dict) -> InitErrorDetails:
    """A pydantic error as raised (ValidationError.errors()) -> the same error, to raise again."""
    ctx = err.get("ctx")
    if err["type"] in _KNOWN_ERRORS:
        detail = InitErrorDetails(type=err["type"], loc=err["loc"], input=err.get("input"))
        if ctx is not None:
            detail["ctx"] = ctx
        return detail
    custom = PydanticCustomError(err["type"], "{message}", {**(ctx or {}), "message": err["msg"]})
    return InitErrorDetails(type=custom, loc=err["loc"], input=err.get("input"))


@functools.cache
def _field_adapter(model: type[BaseModel], name: str) -> TypeAdapter:
    field = model.model_fields[name]
    return TypeAdapter(Annotated[field.annotation, field])


class _Partial:
    """The valid fields of a model input whose validation failed: each field is validated alone on
    first use; a field that failed (or is missing) is not there at all, so `_has` says False."""

    def __init__(self, model: type[BaseModel], data: dict, failed: set, context: Any):
        self._model, self._data, self._failed, self._context = model, data, failed, context
        self.model_fields_set = {k for k in data if k in model.model_fields}

    def __getattr__(self, name: str) -> Any:
        field = self._model.model_fields.get(name)
        if field is None or name in self._failed:
            raise AttributeError(name)
        if name in self._data:
            try:
                value = _field_adapter(self._model, name).validate_python(self._data[name], context=self._context)
            except ValidationError:
                raise AttributeError(name) from None
        elif field.is_required():
            raise AttributeError(name)
        else:
            value = field.get_default(call_default_factory=True)
        setattr(self, name, value)
        return value


def _has(v: Any, *names: str) -> bool:
    """True when the fields `names` of a model (or a _Partial) are valid, so a check may read them."""
    return all(hasattr(v, n) for n in names)


class _Model(BaseModel):
    """Base of every scene model: unknown keys are errors, and every independent error is reported.

    Checks between fields (`_checks`) run on the valid model, and also when some fields failed: then
    on the fields that are valid (`_Partial`), so fixing one error never reveals another that was
    there all along. A check reads only what `_has` says is valid."""

    model_config = ConfigDict(extra="forbid")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        """(location relative to the model, message) of each failed check between fields."""
        return []

    @model_validator(mode="wrap")
    @classmethod
    def _every_error(cls, data: Any, handler, info: ValidationInfo) -> Any:
        if cls._checks.__func__ is _Model._checks.__func__:
            return handler(data)
        try:
            model = handler(data)
        except ValidationError as exc:
            if not isinstance(data, dict):
                raise
            errors = exc.errors()
            failed = {e["loc"][0] for e in errors if e["loc"]}
            found = cls._checks(_Partial(cls, data, failed, info.context), info)
            if not found:
                raise
            extra = [InitErrorDetails(type=_error(msg), loc=loc, input=None) for loc, msg in found]
            raise ValidationError.from_exception_data(cls.__name__, [*map(_details, errors), *extra]) from None
        _raise_at(cls._checks(model, info))
        return model


# ---------------------------------------------------------------------------------------------
# Camera, film, sampler, render settings, fog.


class Camera(_Model):
    """Pinhole or thin-lens camera; the lens and shutter make depth of field and motion blur."""

    lookfrom: Vec3 = Field(description="Eye position (world units).")
    lookat: Vec3 = Field(description="Point the camera looks at (world units).")
    vup: Dir3 = Field((0.0, 1.0, 0.0), description="World 'up' direction; fixes the roll of the camera.")
    vfov: Num = Field(40.0, gt=0, lt=180, description="FULL vertical field of view (degrees).")
    lens_radius: Num = Field(0.0, ge=0, description="Thin-lens aperture radius (world units); 0 = pinhole.")
    focus_distance: Positive | None = Field(
        None, description="Distance to the focal plane (world units); null = |lookat - lookfrom|."
    )
    shutter: Pair = Field((0.0, 1.0), description="Shutter [open, close] time; each ray gets T = T0 + u (T1 - T0).")
    instants: Int | None = Field(
        None,
        ge=1,
        le=1024,
        description="null: each ray's time is continuous in the shutter; N: sample s is taken at instant "
        "T0 + (s mod N + 0.5) (T1 - T0) / N (N frames averaged; temporal aliasing).",
    )

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        errors = []
        if _has(v, "lookat", "lookfrom"):
            forward = _sub(v.lookat, v.lookfrom)
            if _length(forward) == 0:
                errors.append((("lookat",), "must differ from lookfrom (no view direction)"))
            elif _has(v, "vup") and _parallel(forward, v.vup):
                errors.append((("vup",), "must not be parallel to the view direction (lookat - lookfrom)"))
        if _has(v, "shutter") and v.shutter[1] < v.shutter[0]:
            errors.append((("shutter",), "close time must be >= open time"))
        return errors


FILTER_RADIUS = {"box": 0.5, "tent": 1.0, "gaussian": 1.5, "mitchell": 2.0}


class Filter(_Model):
    """Pixel reconstruction filter."""

    type: Literal["box", "tent", "gaussian", "mitchell"] = Field("box", description="Filter shape.")
    radius: Positive | None = Field(
        None,
        description="Filter radius (pixels); null = the type's default: box 0.5, tent 1, gaussian 1.5, mitchell 2.",
    )

    @model_validator(mode="after")
    def _default_radius(self) -> "Filter":
        if self.radius is None:  # filled in without marking the field as set by the user
            object.__setattr__(self, "radius", FILTER_RADIUS[self.type])
        return self


class Film(_Model):
    """The image: resolution, reconstruction filter, exposure."""

    width: Int = Field(256, ge=1, description="Image width (pixels).")
    height: Int = Field(256, ge=1, description="Image height (pixels).")
    filter: Filter = Field(default_factory=Filter, description="Reconstruction filter.")
    exposure: Num = Field(0.0, description="Exposure (stops); the PNG stores sRGB(clamp(2^exposure L)).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        limits, errors = _limits(info), []
        if _has(v, "width") and v.width > limits.max_width:
            errors.append((("width",), limits.at_most("max_width")))
        if _has(v, "height") and v.height > limits.max_height:
            errors.append((("height",), limits.at_most("max_height")))
        if not errors and _has(v, "width", "height") and v.width * v.height > limits.max_pixels:
            pixels = v.width * v.height
            errors.append((("height",), f"width x height = {pixels} pixels; {limits.at_most('max_pixels')}"))
        return errors


class Sampler(_Model):
    """Where in each pixel the samples go (and, for adaptive, how many)."""

    type: SamplerType = Field("jittered", description="Sample pattern in the pixel.")
    spp: Int | None = Field(
        None,
        ge=1,
        description="Samples per pixel; null = 1 for center, 16 otherwise. "
        "center: exactly 1; grid, jittered: a perfect square.",
        # the default as data for editors (the page's form); tests/test_samples.py keeps it equal to _default_spp
        json_schema_extra={
            "x-default-by-type": {
                "center": 1,
                "grid": 16,
                "random": 16,
                "jittered": 16,
                "adaptive": 16,
                "lowdiscrepancy": 16,
            }
        },
    )
    threshold: Num = Field(
        0.05, ge=0, description="adaptive: largest colour difference of a cell still called uniform."
    )
    max_level: Int = Field(3, ge=0, le=8, description="adaptive: subdivision limit (levels).")
    jitter: Bool = Field(False, description="adaptive: random sample positions inside the cells.")

    @model_validator(mode="after")
    def _default_spp(self) -> "Sampler":
        if self.spp is None:  # filled in without marking the field as set by the user
            object.__setattr__(self, "spp", 1 if self.type == "center" else 16)
        return self

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        kind = v.type if _has(v, "type") else None
        spp = v.spp if _has(v, "spp") else None
        if spp is None and kind is not None:
            spp = 1 if kind == "center" else 16
        if spp is None:
            return []
        limits, errors = _limits(info), []
        root = math.isqrt(spp)
        if kind == "center" and spp != 1:
            errors.append((("spp",), "must be 1 for the center sampler"))
        elif kind in ("grid", "jittered") and root * root != spp:
            nearest = f"{root * root} or {(root + 1) ** 2}"
            errors.append((("spp",), f"must be a perfect square for the {kind} sampler (e.g. {nearest})"))
        elif spp > limits.max_spp:
            errors.append((("spp",), limits.at_most("max_spp")))
        return errors


class RadiositySettings(_Model):
    """The radiosity integrator's solution and how it is shown (an addition to the format)."""

    patch_size: Num = Field(
        0.25,
        gt=0,
        description="Patch edge length (world units) of the meshed surfaces; the patches it makes are counted, "
        "before any is made, against the service's limit (TRACER_MAX_PATCHES).",
    )
    display: Literal["two-pass", "flat", "smooth"] = Field(
        "two-pass",
        description="two-pass: the ray tree with the radiosity solution as its diffuse interreflection; "
        "flat: each patch's radiosity; smooth: radiosity interpolated from the patch corners.",
    )
    rays: Int = Field(
        4096,
        ge=16,
        le=1_000_000,
        description="Form-factor rays per shot; rays x max_steps is bounded by the service (TRACER_MAX_SOLVE_RAYS).",
    )
    threshold: Num = Field(0.01, gt=0, le=1, description="Stop when the unshot power is below this share of all.")
    max_steps: Int = Field(2000, ge=1, le=100_000, description="At most this many shots.")


class RenderSettings(_Model):
    """Which integrator, and where the ray tree stops."""

    integrator: IntegratorName = Field(
        "whitted",
        description="Light transport method.",
        json_schema_extra={"x-integrators": [{"name": i.name, "description": i.description} for i in INTEGRATORS]},
    )
    max_depth: Int = Field(
        5, ge=1, le=64, description="Bounces of light on the way to the eye; 1 = ray casting with shadows."
    )
    min_weight: Num = Field(0.001, ge=0, description="Stop a branch once its weight (product of K's) falls below this.")
    light_samples: Int = Field(1, ge=1, description="Shadow rays per area light per shading point.")
    seed: Int = Field(0, ge=0, lt=2**31, description="Random seed; same scene and seed give the same image.")
    radiosity: RadiositySettings = Field(
        default_factory=RadiositySettings, description="Settings of the radiosity integrator."
    )

    @property
    def integrator_info(self) -> IntegratorInfo:
        """The integrator's row of the table (tracer/integrators/__init__.py): its pre-pass, its cost."""
        return BY_NAME[self.integrator]

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        limits, errors = _limits(info), []
        if _has(v, "max_depth") and v.max_depth > limits.max_depth:
            errors.append((("max_depth",), limits.at_most("max_depth")))
        if _has(v, "light_samples") and v.light_samples > limits.max_light_samples:
            errors.append((("light_samples",), limits.at_most("max_light_samples")))
        return errors


class Fog(_Model):
    """Fog on eye, reflection and transmission rays: e^(-density t) L + (1 - e^(-density t)) color."""

    density: Num = Field(0.0, ge=0, description="Extinction coefficient (1 / world unit); 0 = no fog.")
    color: RGB = Field((0.5, 0.5, 0.5), description="Fog radiance (linear RGB).")


# ---------------------------------------------------------------------------------------------
# Materials (Phong, as in the lecture).


class CheckerTexture(_Model):
    """Solid 3D checker: color1 where floor(x/size) + floor(y/size) + floor(z/size) is even."""

    type: Literal["checker"] = Field(description="Texture type.")
    size: Num = Field(1.0, gt=0, description="Cell size (world units).")
    color1: RGB = Field((0.8, 0.8, 0.8), description="Colour of the even cells (linear RGB).")
    color2: RGB = Field((0.2, 0.2, 0.2), description="Colour of the odd cells (linear RGB).")


class ImageTexture(_Model):
    """An image looked up at the surface's (u, v)."""

    type: Literal["image"] = Field(description="Texture type.")
    file: ImageFile = Field(
        description="Image file in the asset folder, or a data: URI; its pixels count against the service's "
        "limits on one image and on all of a scene's (read from its header)."
    )
    scale: Pair = Field((1.0, 1.0), description="Repeats of the image along u and v.")


class NoiseBump(_Model):
    """Bump mapping by a solid noise function."""

    type: Literal["noise"] = Field(description="Bump type.")
    scale: Num = Field(1.0, gt=0, description="Frequency of the noise (cells per world unit): larger is finer.")
    strength: Num = Field(1.0, ge=0, description="Height of the bumps (dimensionless gain).")


class ImageBump(_Model):
    """Bump mapping by a height image looked up at the surface's (u, v)."""

    type: Literal["image"] = Field(description="Bump type.")
    file: ImageFile = Field(
        description="Height image in the asset folder, or a data: URI; its pixels count against the service's "
        "limits on one image and on all of a scene's (read from its header)."
    )
    strength: Num = Field(1.0, ge=0, description="Height of the bumps (dimensionless gain).")
    scale: Pair = Field((1.0, 1.0), description="Repeats of the image along u and v.")


Texture = Annotated[CheckerTexture | ImageTexture, Field(discriminator="type")]
Bump = Annotated[NoiseBump | ImageBump, Field(discriminator="type")]


class Material(_Model):
    """Phong material with reflection and transmission rays; coefficients are linear RGB."""

    kd: RGB = Field((0.5, 0.5, 0.5), description="Diffuse reflectance (albedo).")
    ka: RGB | None = Field(
        None,
        description="Ambient coefficient, times the scene's ambient (whitted); null = kd after texturing.",
    )
    ks: RGB = Field((0.0, 0.0, 0.0), description="Specular coefficient of the Phong highlight.")
    shininess: Num = Field(32.0, ge=0, description="Phong exponent n of the highlight.")
    kr: RGB = Field((0.0, 0.0, 0.0), description="Weight of the reflection ray.")
    kt: RGB = Field((0.0, 0.0, 0.0), description="Weight of the transmission (refraction) ray.")
    ior: Num = Field(1.5, gt=0, description="Index of refraction inside the surface (outside is 1).")
    fresnel: Bool = Field(
        False,
        description="Scale reflection and transmission weights by the dielectric Fresnel terms R, 1 - R.",
    )
    gloss: Positive | None = Field(
        None,
        description="null: perfect mirror/refraction rays; "
        "m: directions spread in a cos^m lobe (glossy reflection, frosted glass).",
    )
    emission: RGB = Field((0.0, 0.0, 0.0), description="Emitted radiance (W / (m^2 sr)).")
    texture: Texture | None = Field(None, description="Replaces kd: a checker or an image texture.")
    bump: Bump | None = Field(None, description="Perturbs the shading normal: noise or a height image.")


def _material_kind(v: Any) -> str | None:
    return "name" if isinstance(v, str) else "inline" if isinstance(v, dict | Material) else None


MaterialRef = Annotated[
    Annotated[str, Tag("name")] | Annotated[Material, Tag("inline")],
    Discriminator(
        _material_kind,
        custom_error_type="scene",
        custom_error_message="expected a material name (a key of 'materials') or an inline material object",
    ),
]


# ---------------------------------------------------------------------------------------------
# Lights.


class PointLight(_Model):
    """Point light, invisible to rays."""

    type: Literal["point"] = Field(description="Light type.")
    position: Vec3 = Field(description="Position (world units).")
    intensity: RGB = Field((1.0, 1.0, 1.0), description="Radiant intensity (W/sr).")
    attenuation: Attenuation = Field(
        (0.0, 0.0, 1.0),
        description="[c1, c2, c3] of f_att = 1 / (c1 + c2 d + c3 d^2); default inverse square.",
    )


class DirectionalLight(_Model):
    """Distant light from one direction, invisible to rays."""

    type: Literal["directional"] = Field(description="Light type.")
    direction: Dir3 = Field(description="The way the light travels (need not be normalised).")
    irradiance: RGB = Field((1.0, 1.0, 1.0), description="Irradiance at normal incidence (W/m^2).")


class SpotLight(_Model):
    """Point light restricted to a cone, invisible to rays."""

    type: Literal["spot"] = Field(description="Light type.")
    position: Vec3 = Field(description="Position (world units).")
    direction: Dir3 = Field(description="Axis of the cone, the way the light travels.")
    intensity: RGB = Field((1.0, 1.0, 1.0), description="Radiant intensity on the axis (W/sr).")
    cutoff: Num = Field(gt=0, le=180, description="Half-angle of the cone (degrees).")
    falloff: Num = Field(0.0, ge=0, description="Exponent of (cos psi)^falloff inside the cone.")
    attenuation: Attenuation = Field(
        (0.0, 0.0, 1.0),
        description="[c1, c2, c3] of f_att = 1 / (c1 + c2 d + c3 d^2); default inverse square.",
    )


class QuadLight(_Model):
    """Parallelogram area light; emits on the side of normalize(edge1 x edge2)."""

    type: Literal["quad"] = Field(description="Light type.")
    corner: Vec3 = Field(description="One corner (world units).")
    edge1: Dir3 = Field(description="First edge from the corner (world units).")
    edge2: Dir3 = Field(description="Second edge from the corner (world units).")
    radiance: RGB = Field((1.0, 1.0, 1.0), description="Emitted radiance (W / (m^2 sr)).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if _has(v, "edge1", "edge2") and _parallel(v.edge1, v.edge2):
            return [(("edge2",), "must not be parallel to edge1 (degenerate quad)")]
        return []


class DiskLight(_Model):
    """Disk area light; emits on the side of `normal`."""

    type: Literal["disk"] = Field(description="Light type.")
    center: Vec3 = Field(description="Centre (world units).")
    normal: Dir3 = Field(description="Normal; the disk emits on this side.")
    radius: Num = Field(gt=0, description="Radius (world units).")
    radiance: RGB = Field((1.0, 1.0, 1.0), description="Emitted radiance (W / (m^2 sr)).")


class SphereLight(_Model):
    """Spherical area light; emits outwards."""

    type: Literal["sphere"] = Field(description="Light type.")
    center: Vec3 = Field(description="Centre (world units).")
    radius: Num = Field(gt=0, description="Radius (world units).")
    radiance: RGB = Field((1.0, 1.0, 1.0), description="Emitted radiance (W / (m^2 sr)).")


Light = Annotated[
    PointLight | DirectionalLight | SpotLight | QuadLight | DiskLight | SphereLight,
    Field(discriminator="type"),
]
AREA_LIGHTS = (QuadLight, DiskLight, SphereLight)  # lights with a surface: visible, sampled over their area
LIGHT_TYPES = {get_args(m.model_fields["type"].annotation)[0]: m for m in get_args(get_args(Light)[0])}  # "point": ...
AREA_LIGHT_TYPES = [t for t, m in LIGHT_TYPES.items() if m in AREA_LIGHTS]  # "quad", "disk", "sphere"


# ---------------------------------------------------------------------------------------------
# Objects.


class Transform(_Model):
    """Applied scale, then rotate (about X, then Y, then Z), then translate."""

    translate: Vec3 = Field((0.0, 0.0, 0.0), description="Translation (world units).")
    rotate: Vec3 = Field((0.0, 0.0, 0.0), description="Rotations about X, Y, Z (degrees).")
    scale: Scale3 = Field((1.0, 1.0, 1.0), description="Scale factor, or [sx, sy, sz]; non-zero.")


class _Object(_Model):
    type: str = Field(description="Object type.")
    material: MaterialRef = Field(description="A material name from 'materials', or an inline material.")
    name: Str | None = Field(None, description="Name shown in the ray tree.")
    velocity: Vec3 = Field(
        (0.0, 0.0, 0.0),
        description="World units per unit time; at ray time T the object is at p + velocity T.",
    )

    @field_validator("material")
    @classmethod
    def _known_material(cls, v: Any, info: ValidationInfo) -> Any:
        names = (info.context or {}).get("material_names")
        if isinstance(v, str) and names is not None and v not in names:
            raise _error(_unknown_material(v, names))
        return v


def _unknown_material(name: str, names) -> str:
    close = difflib.get_close_matches(name, sorted(names), n=1)
    hint = f"; did you mean '{close[0]}'?" if close else f" (defined: {', '.join(sorted(names)) or 'none'})"
    return f"material '{name}' is not defined in 'materials'{hint}"


class Sphere(_Object):
    """Sphere; geometric normal outwards."""

    type: Literal["sphere"] = Field(description="Object type.")
    center: Vec3 = Field(description="Centre (world units).")
    radius: Num = Field(gt=0, description="Radius (world units).")


class Plane(_Object):
    """Infinite two-sided plane."""

    type: Literal["plane"] = Field(description="Object type.")
    point: Vec3 = Field(description="A point on the plane (world units).")
    normal: Dir3 = Field(description="Geometric normal.")


class Quad(_Object):
    """Parallelogram corner + s edge1 + t edge2, s, t in [0, 1]; normal normalize(edge1 x edge2)."""

    type: Literal["quad"] = Field(description="Object type.")
    corner: Vec3 = Field(description="One corner (world units).")
    edge1: Dir3 = Field(description="First edge from the corner (world units).")
    edge2: Dir3 = Field(description="Second edge from the corner (world units).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if _has(v, "edge1", "edge2") and _parallel(v.edge1, v.edge2):
            return [(("edge2",), "must not be parallel to edge1 (degenerate quad)")]
        return []


class Disk(_Object):
    """Flat disk, two-sided."""

    type: Literal["disk"] = Field(description="Object type.")
    center: Vec3 = Field(description="Centre (world units).")
    normal: Dir3 = Field(description="Geometric normal.")
    radius: Num = Field(gt=0, description="Radius (world units).")


class Box(_Object):
    """Axis-aligned box [min, max], optionally transformed; normals outwards."""

    type: Literal["box"] = Field(description="Object type.")
    min: Vec3 = Field(description="Minimum corner (world units, before the transform).")
    max: Vec3 = Field(description="Maximum corner (world units, before the transform).")
    transform: Transform | None = Field(None, description="Scale, rotate, translate applied to the box.")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if not _has(v, "min", "max"):
            return []
        return [
            (("max", axis), f"must be greater than min[{axis}] = {v.min[axis]:g}")
            for axis in range(3)
            if v.max[axis] <= v.min[axis]
        ]


class Triangle(_Object):
    """One triangle; geometric normal normalize((v1 - v0) x (v2 - v0))."""

    type: Literal["triangle"] = Field(description="Object type.")
    vertices: Annotated[
        tuple[Vec3, Vec3, Vec3], BeforeValidator(_triple("three vertices [[x, y, z], [x, y, z], [x, y, z]]"))
    ] = Field(description="The three vertices v0, v1, v2 (world units).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if _has(v, "vertices"):
            v0, v1, v2 = v.vertices
            if _parallel(_sub(v1, v0), _sub(v2, v0)):
                return [(("vertices",), "the three vertices are collinear (degenerate triangle)")]
        return []


class Mesh(_Object):
    """Triangle mesh: inline vertices + faces, or a file (OBJ/PLY/glTF) from the asset folder."""

    type: Literal["mesh"] = Field(description="Object type.")
    vertices: list[Vec3] | None = Field(None, min_length=1, description="Inline vertex positions (world units).")
    faces: list[Face] | None = Field(
        None,
        min_length=1,
        description="Inline triangles as vertex indices [i, j, k] (0-based, counter-clockwise).",
    )
    file: MeshFile | None = Field(None, description="Mesh file in the asset folder, or a data: URI.")
    transform: Transform | None = Field(None, description="Scale, rotate, translate applied to the mesh.")
    smooth: Bool = Field(False, description="Interpolate vertex normals (smooth shading).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        def given(field: str) -> bool:  # set to something other than null (valid or not)
            return field in v.model_fields_set and (not _has(v, field) or getattr(v, field) is not None)

        errors = []
        if given("file"):
            if given("vertices") or given("faces"):
                errors.append((("file",), "give either 'file' or inline 'vertices' + 'faces', not both"))
        else:
            for field in ("vertices", "faces"):
                if not given(field):
                    errors.append(((field,), f"required field '{field}' is missing (or give a 'file')"))
        if _has(v, "vertices", "faces") and v.vertices is not None and v.faces is not None:
            n, bad = len(v.vertices), []
            for k, face in enumerate(v.faces):
                bad += [(k, j, i) for j, i in enumerate(face) if not 0 <= i < n]
            for k, j, i in bad[:10]:
                errors.append((("faces", k, j), f"vertex index {i} is out of range (the mesh has {n} vertices)"))
            if len(bad) > 10:
                errors.append((("faces",), f"{len(bad) - 10} more vertex indices are out of range"))
        return errors


Object = Annotated[Sphere | Plane | Quad | Disk | Box | Triangle | Mesh, Field(discriminator="type")]


def primitive_count(objects: list) -> int:
    """Primitives the renderer will build: a box is 12 triangles, an inline mesh its faces.

    Meshes from files are not counted here (their size is known when the file is read)."""
    return sum(len(o.faces or ()) if isinstance(o, Mesh) else 12 if isinstance(o, Box) else 1 for o in objects)


def _file_triangles(objects: list, info: ValidationInfo) -> dict[int, int]:
    """Object index -> triangles of its mesh file, when validation resolves assets (read once: cached)."""
    folder, out = _asset_dir(info), {}
    if folder is None:
        return out
    for i, o in enumerate(objects):
        if isinstance(o, Mesh) and o.file is not None:
            try:
                out[i] = len(read_mesh(o.file, folder)[1])
            except AssetError:  # reported at objects[i].file
                pass
    return out


def image_files(materials: dict, objects: list) -> list[tuple[tuple, str]]:
    """(location, file) of every image texture and bump of a scene, in the order the renderer loads them:
    the named materials', then the objects' own (tracer/compile.py). A location names the tags of the
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
    triangles = meshing.mesh_triangles(v.objects, meshing.mesh_files(_asset_dir(info)))
    problems = meshing.solve_problems(v, triangles, v.render.radiosity, _limits(info))
    return [(("render", "radiosity", field), message) for field, message in problems]


# ---------------------------------------------------------------------------------------------
# The scene.


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


# ---------------------------------------------------------------------------------------------
# Warnings: settings that have no effect.


def _material_warnings(m: Material, at: list, warn) -> None:
    opaque = not any(m.kt)
    if "ior" in m.model_fields_set and opaque:
        warn([*at, "ior"], "has no effect: the material is opaque (kt = 0)")
    if m.fresnel and opaque and not any(m.kr):
        warn([*at, "fresnel"], "has no effect: the material neither reflects nor transmits (kr = kt = 0)")
    if m.gloss is not None and opaque and not any(m.kr):
        warn([*at, "gloss"], "has no effect: the material neither reflects nor transmits (kr = kt = 0)")
    if max(m.kd) > 1:
        warn([*at, "kd"], "a component > 1 reflects more light than arrives (not energy conserving)")


def _warnings(scene: Scene) -> list[dict[str, str]]:
    out: list[dict[str, str]] = []

    def warn(parts: list, message: str) -> None:
        out.append({"path": json_path(parts), "message": message})

    camera, sampler, render = scene.camera, scene.sampler, scene.render
    if "shutter" in camera.model_fields_set and not any(any(o.velocity) for o in scene.objects):
        warn(["camera", "shutter"], "has no effect: nothing moves (no object has a non-zero velocity)")
    if camera.instants is not None:
        if not any(any(o.velocity) for o in scene.objects):
            warn(["camera", "instants"], "has no effect: nothing moves (no object has a non-zero velocity)")
        elif sampler.type != "adaptive" and sampler.spp % camera.instants:
            warn(
                ["camera", "instants"],
                f"the {camera.instants} instants are not used equally: spp ({sampler.spp}) is not a multiple of it",
            )
    if camera.focus_distance is not None and camera.lens_radius == 0:
        warn(["camera", "focus_distance"], "has no effect with a pinhole camera (lens_radius = 0)")
    if sampler.type != "adaptive":
        for field in ("threshold", "max_level", "jitter"):
            if field in sampler.model_fields_set:
                warn(
                    ["sampler", field],
                    f"has no effect: only the adaptive sampler uses it (type is {sampler.type})",
                )
    if sampler.type == "adaptive":
        if "spp" in sampler.model_fields_set:
            warn(["sampler", "spp"], "has no effect: the adaptive sampler decides how many rays each pixel gets")
        if "filter" in scene.film.model_fields_set:
            warn(["film", "filter"], "has no effect: the adaptive sampler averages its cells (a box filter)")
    solves = render.integrator_info.prepass == "radiosity"  # the radiosity solution, before the render
    if "radiosity" in render.model_fields_set and not solves:
        warn(["render", "radiosity"], f"has no effect: the integrator is {render.integrator}")
    if solves:
        for i, obj in enumerate(scene.objects):
            if any(obj.velocity):
                warn(
                    ["objects", i, "velocity"],
                    "the radiosity solution is solved with every object where it is at time 0: this object's "
                    "light and shadows in it do not move with it (it still blurs in the image)",
                )
    if render.light_samples > 1 and not any(isinstance(light, AREA_LIGHTS) for light in scene.lights):
        warn(["render", "light_samples"], "has no effect: the scene has no area light (quad, disk, sphere)")
    if "color" in scene.fog.model_fields_set and scene.fog.density == 0:
        warn(["fog", "color"], "has no effect: fog density is 0")
    for name, material in scene.materials.items():
        _material_warnings(material, ["materials", name], warn)
    for i, obj in enumerate(scene.objects):
        if isinstance(obj.material, Material):
            _material_warnings(obj.material, ["objects", i, "material"], warn)
    for i, light in enumerate(scene.lights):
        power = "intensity" if isinstance(light, PointLight | SpotLight) else None
        power = power or ("irradiance" if isinstance(light, DirectionalLight) else "radiance")
        if not any(getattr(light, power)):
            warn(["lights", i, power], "is zero: this light contributes nothing")
    return out


# ---------------------------------------------------------------------------------------------
# Public entry points.


def _scene_file(text: str) -> Path | None:
    """The text as the path of an existing file, or None (it is not one, or cannot be one)."""
    if "\n" in text or len(text) > 4096:
        return None
    try:
        path = Path(text)
        return path if path.is_file() else None
    except (OSError, ValueError):  # a NUL byte, a name too long
        return None


def _not_json(text: str, e: json.JSONDecodeError) -> str:
    """Why a text that is not JSON is not a scene either (it is no file's path)."""
    where = f"line {e.lineno}, column {e.colno}"
    if not text.strip():
        return "the scene text is empty: expected JSON {...} or the path of a scene file"
    if text.lstrip()[:1] in ("{", "["):
        return f"invalid JSON at {where}: {e.msg}"
    if "\n" not in text and (text.strip().lower().endswith(".json") or "/" in text or "\\" in text):
        return f"cannot read scene file {text}: no such file (and the text is not JSON either)"
    shown = text.strip()[:40] + ("..." if len(text.strip()) > 40 else "")
    return f"'{shown}' is neither JSON (invalid JSON at {where}: {e.msg}) nor the path of a scene file"


def _parse(src: Any) -> dict:
    """dict, JSON text (str or bytes), or a scene file's path (Path or str) -> the scene dict."""
    if isinstance(src, str) and src.lstrip()[:1] not in ("{", "["):
        src = _scene_file(src) or src  # "scenes/cornell.json" is a path; '{"camera": ...}' is JSON
    if isinstance(src, Path):
        try:
            src = src.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise SceneError([{"path": "", "message": f"cannot read scene file {src}: {e}"}]) from None
    if isinstance(src, bytes | bytearray):
        try:
            src = src.decode("utf-8")
        except UnicodeDecodeError as e:
            raise SceneError([{"path": "", "message": f"scene is not UTF-8 text: {e}"}]) from None
    if isinstance(src, str):
        try:
            src = json.loads(src)
        except json.JSONDecodeError as e:
            raise SceneError([{"path": "", "message": _not_json(src, e)}]) from None
        except (ValueError, RecursionError) as e:  # e.g. an integer of more than 4300 digits
            raise SceneError([{"path": "", "message": f"invalid JSON: {e}"}]) from None
    if not isinstance(src, dict):
        raise SceneError([{"path": "", "message": f"a scene must be a JSON object {{...}}, got {show_value(src)}"}])
    return src


def load_scene(
    src: Any, limits: Limits | None = None, assets: Path | str | None = None
) -> tuple[Scene, list[dict[str, str]]]:
    """Parse and validate a scene: (Scene, warnings). Raises SceneError listing every error.

    `src`: a dict, JSON text (str or bytes), or the path of a scene file (Path or str).
    `assets`: the asset folder (ASSET_DIR is the default one) to resolve the scene's files in, so that
    a missing or unreadable mesh or image, a data: URI that is not one, and the triangles of mesh files
    past `limits.max_primitives` are errors here too, at their JSON paths. None checks the format
    only (the renderer reads the files, and says what is wrong with them, when it compiles the scene).
    """
    data = _parse(src)
    materials = data.get("materials")
    context = {
        "limits": limits or Limits(),
        "material_names": set(materials) if isinstance(materials, dict) else None,
        "assets": None if assets is None else Path(assets),
    }
    try:
        scene = Scene.model_validate(data, context=context)
    except ValidationError as e:
        raise SceneError(pydantic_errors(e, Scene)) from None
    return scene, _warnings(scene)


def validate_scene(src: Any, limits: Limits | None = None, assets: Path | str | None = None) -> dict:
    """{"valid": bool, "errors": [...], "warnings": [...]}; never raises for a bad scene.

    With `assets` (a folder, see `load_scene`) the scene's files are resolved and checked too."""
    try:
        _, warnings = load_scene(src, limits, assets)
    except SceneError as e:
        return {"valid": False, "errors": e.errors, "warnings": []}
    return {"valid": True, "errors": [], "warnings": warnings}


def scene_json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a scene, generated from the models, with descriptions."""
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **Scene.model_json_schema()}
