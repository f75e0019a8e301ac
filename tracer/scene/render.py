"""How light is carried to the eye: the integrator (a row of the table in tracer/scene/integrators.py)
and where its ray tree stops, the radiosity solution's settings, and the fog light passes through."""

from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, ValidationInfo

from tracer.scene.base import _has, _Model
from tracer.scene.context import _limits
from tracer.scene.integrators import BY_NAME, INTEGRATORS, IntegratorInfo
from tracer.scene.integrators import NAMES as INTEGRATOR_NAMES
from tracer.scene.values import RGB, Int, Num

if TYPE_CHECKING:  # a Literal made from the table at run time, which pyright cannot read: a str to it
    IntegratorName = str
else:
    IntegratorName = Literal[INTEGRATOR_NAMES]  # "whitted", "path", ...: the table in tracer/scene/integrators.py


class RadiositySettings(_Model):
    """The radiosity integrator's solution and how it is shown (an addition to the format)."""

    patch_size: Num = Field(
        default=0.25,
        gt=0,
        description="Patch edge length (world units) of the meshed surfaces; the patches it makes are counted, "
        "before any is made, against the service's limit (TRACER_MAX_PATCHES).",
    )
    display: Literal["two-pass", "flat", "smooth"] = Field(
        default="two-pass",
        description="two-pass: the ray tree with the radiosity solution as its diffuse interreflection; "
        "flat: each patch's radiosity; smooth: radiosity interpolated from the patch corners.",
    )
    rays: Int = Field(
        default=4096,
        ge=16,
        le=1_000_000,
        description="Form-factor rays per shot; rays x max_steps is bounded by the service (TRACER_MAX_SOLVE_RAYS).",
    )
    threshold: Num = Field(
        default=0.01, gt=0, le=1, description="Stop when the unshot power is below this share of all."
    )
    max_steps: Int = Field(default=2000, ge=1, le=100_000, description="At most this many shots.")


class RenderSettings(_Model):
    """Which integrator, and where the ray tree stops."""

    integrator: IntegratorName = Field(
        default="whitted",
        description="Light transport method.",
        json_schema_extra={"x-integrators": [{"name": i.name, "description": i.description} for i in INTEGRATORS]},
    )
    max_depth: Int = Field(
        default=5, ge=1, le=64, description="Bounces of light on the way to the eye; 1 = ray casting with shadows."
    )
    min_weight: Num = Field(
        default=0.001, ge=0, description="Stop a branch once its weight (product of K's) falls below this."
    )
    light_samples: Int = Field(default=1, ge=1, description="Shadow rays per area light per shading point.")
    seed: Int = Field(default=0, ge=0, lt=2**31, description="Random seed; same scene and seed give the same image.")
    radiosity: RadiositySettings = Field(
        default_factory=RadiositySettings, description="Settings of the radiosity integrator."
    )

    @property
    def integrator_info(self) -> IntegratorInfo:
        """The integrator's row of the table (tracer/scene/integrators.py): its pre-pass, its cost."""
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

    density: Num = Field(default=0.0, ge=0, description="Extinction coefficient (1 / world unit); 0 = no fog.")
    color: RGB = Field(default=(0.5, 0.5, 0.5), description="Fog radiance (linear RGB).")
