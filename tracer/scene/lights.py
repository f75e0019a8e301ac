"""Light sources: point, directional and spot lights (invisible to rays), and the area lights (quad,
disk, sphere), which have a surface: visible, and sampled over their area (tracer/kernels/lights.py)."""

from typing import Annotated, Any, Literal, get_args

from pydantic import Field, ValidationInfo

from tracer.scene.base import _has, _Model
from tracer.scene.values import RGB, Attenuation, Dir3, Num, Vec3, _parallel


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
