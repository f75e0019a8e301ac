"""The eye and the image: the camera (pinhole or thin lens, with a shutter), the film and its
reconstruction filter, and the sampler that places the samples in each pixel."""

import math
from typing import Any, Literal

from pydantic import Field, ValidationInfo, model_validator

from tracer.scene.base import _has, _Model
from tracer.scene.context import _limits
from tracer.scene.values import Bool, Dir3, Int, Num, Pair, Positive, Vec3, _length, _parallel, _sub

SamplerType = Literal["center", "grid", "random", "jittered", "adaptive", "lowdiscrepancy"]


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

    type: Literal["box", "tent", "gaussian", "mitchell"] = Field(default="box", description="Filter shape.")
    radius: Positive | None = Field(
        default=None,
        description="Filter radius (pixels); null = the type's default: box 0.5, tent 1, gaussian 1.5, mitchell 2.",
    )

    @model_validator(mode="after")
    def _default_radius(self) -> "Filter":
        if self.radius is None:  # filled in without marking the field as set by the user
            object.__setattr__(self, "radius", FILTER_RADIUS[self.type])
        return self


class Film(_Model):
    """The image: resolution, reconstruction filter, exposure."""

    width: Int = Field(default=256, ge=1, description="Image width (pixels).")
    height: Int = Field(default=256, ge=1, description="Image height (pixels).")
    filter: Filter = Field(default_factory=Filter, description="Reconstruction filter.")
    exposure: Num = Field(default=0.0, description="Exposure (stops); the PNG stores sRGB(clamp(2^exposure L)).")

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

    type: SamplerType = Field(default="jittered", description="Sample pattern in the pixel.")
    spp: Int | None = Field(
        default=None,
        ge=1,
        description="Samples per pixel; null = 1 for center, 16 otherwise. "
        "center: exactly 1; grid, jittered: a perfect square.",
        # the default as data for editors (the page's form); tests/tracer/test_samples.py keeps it equal to _default_spp
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
        default=0.05, ge=0, description="adaptive: largest colour difference of a cell still called uniform."
    )
    max_level: Int = Field(default=3, ge=0, le=8, description="adaptive: subdivision limit (levels).")
    jitter: Bool = Field(default=False, description="adaptive: random sample positions inside the cells.")

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
