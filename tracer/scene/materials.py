"""Materials (Phong, as in the lecture): reflectances, reflection and transmission weights, Fresnel,
gloss, emission; textures and bump maps; and an object's reference to a material, by name or inline."""

import difflib
from typing import Annotated, Any, Literal

from pydantic import Discriminator, Field, Tag

from tracer.scene.base import _Model
from tracer.scene.context import ImageFile
from tracer.scene.values import RGB, Bool, Num, Pair, Positive


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
        description="Image file (PNG or JPEG) in the asset folder, or a data: URI; its pixels count against the "
        "service's limits on one image and on all of a scene's (read from its header)."
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
        description="Height image (PNG or JPEG) in the asset folder, or a data: URI; its pixels count against the "
        "service's limits on one image and on all of a scene's (read from its header)."
    )
    strength: Num = Field(1.0, ge=0, description="Height of the bumps (dimensionless gain).")
    scale: Pair = Field((1.0, 1.0), description="Repeats of the image along u and v.")


Texture = Annotated[CheckerTexture | ImageTexture, Field(discriminator="type")]
Bump = Annotated[NoiseBump | ImageBump, Field(discriminator="type")]


class Material(_Model):
    """Phong material with reflection and transmission rays; coefficients are linear RGB."""

    kd: RGB = Field(default=(0.5, 0.5, 0.5), description="Diffuse reflectance (albedo).")
    ka: RGB | None = Field(
        default=None,
        description="Ambient coefficient, times the scene's ambient (whitted); null = kd after texturing.",
    )
    ks: RGB = Field(default=(0.0, 0.0, 0.0), description="Specular coefficient of the Phong highlight.")
    shininess: Num = Field(default=32.0, ge=0, description="Phong exponent n of the highlight.")
    kr: RGB = Field(default=(0.0, 0.0, 0.0), description="Weight of the reflection ray.")
    kt: RGB = Field(default=(0.0, 0.0, 0.0), description="Weight of the transmission (refraction) ray.")
    ior: Num = Field(default=1.5, gt=0, description="Index of refraction inside the surface (outside is 1).")
    fresnel: Bool = Field(
        default=False,
        description="Scale reflection and transmission weights by the dielectric Fresnel terms R, 1 - R.",
    )
    gloss: Positive | None = Field(
        default=None,
        description="null: perfect mirror/refraction rays; "
        "m: directions spread in a cos^m lobe (glossy reflection, frosted glass).",
    )
    emission: RGB = Field(default=(0.0, 0.0, 0.0), description="Emitted radiance (W / (m^2 sr)).")
    texture: Texture | None = Field(default=None, description="Replaces kd: a checker or an image texture.")
    bump: Bump | None = Field(default=None, description="Perturbs the shading normal: noise or a height image.")


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


def _unknown_material(name: str, names) -> str:
    close = difflib.get_close_matches(name, sorted(names), n=1)
    hint = f"; did you mean '{close[0]}'?" if close else f" (defined: {', '.join(sorted(names)) or 'none'})"
    return f"material '{name}' is not defined in 'materials'{hint}"
