"""The assignment spec: what an instructor asks of a submitted scene, and how many points each is worth.

An assignment is one JSON object, validated like a scene (unknown keys are errors at their JSON
path). docs/grading.md has the full table and a worked example (scenes/grading/assignment.json):

    {"version": 1, "name": "HW 4: glass and soft shadows",
     "render": {"width": 96, "height": 72, "seed": 7},          # the settings every render uses
     "limits": {"max_seconds": 60, "max_spp": 64},               # per student
     "validity": {"points": 1},                                  # a scene that validates
     "requirements": [{"name": "glass", "points": 2, "check": "transmissive_material"},
                      {"name": "three bounces", "points": 1,
                       "check": {"value": "render.max_depth", "at_least": 3}}],
     "reference": {"scene": "reference.json", "spp": 256,
                   "flip": {"points": 2}, "ssim": {"points": 1}, "psnr": {"points": 1},
                   "pixels": {"points": 2}},
     "manual": [{"name": "creativity", "points": 3, "instructions": "Is the scene more than the starter?",
                 "rubric": [{"name": "new objects", "points": 2}, {"name": "a story", "points": 1},
                            {"name": "copied starter", "points": -3, "description": "a deduction"}]}]}

`manual` items are graded by the course's staff (server/course/manual.py), not by this package: each has its
points (the item's most), a rubric of levels (at most 9: a key each on the grading queue) whose chosen ones'
points add up, clamped to 0..points, and instructions for the graders. A level's points lie in -points..points:
a negative one is a deduction (a rubric that starts from full marks lists a level worth `points` and deductions).
Item names are unique in the spec, and level names within their item.
"""

from __future__ import annotations

import difflib
import json
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from tracer.errors import pydantic_errors
from tracer.limits import NAMES as LIMIT_NAMES
from tracer.scene import AREA_LIGHT_TYPES, IntegratorName, Limits, SamplerType, SceneError

COMPARISONS = {  # word -> (symbol for messages, test)
    "equals": ("=", lambda a, b: a == b),
    "at_least": (">=", lambda a, b: a >= b),
    "at_most": ("<=", lambda a, b: a <= b),
    "greater_than": (">", lambda a, b: a > b),
    "less_than": ("<", lambda a, b: a < b),
    "one_of": ("in", lambda a, b: a in b),
}
# Common requirements by name, so an assignment can say {"check": "area_light"}.
PRESETS: dict[str, dict] = {
    "transmissive_material": {
        "count": "materials", "where": {"kt": {"greater_than": 0}, "ior": {"greater_than": 1}}, "at_least": 1,
    },
    "reflective_material": {"count": "materials", "where": {"kr": {"greater_than": 0}}, "at_least": 1},
    "glossy_material": {"count": "materials", "where": {"gloss": {"present": True}}, "at_least": 1},
    "textured_material": {"count": "materials", "where": {"texture": {"present": True}}, "at_least": 1},
    "bump_map": {"count": "materials", "where": {"bump": {"present": True}}, "at_least": 1},
    "area_light": {"count": "lights", "where": {"type": {"one_of": AREA_LIGHT_TYPES}}, "at_least": 1},
    "depth_of_field": {"value": "camera.lens_radius", "greater_than": 0},
    "motion": {"count": "objects", "where": {"velocity": {"present": True}}, "at_least": 1},
    "fog": {"value": "fog.density", "greater_than": 0},
}  # fmt: skip


class AssignmentError(SceneError):
    """An invalid assignment; `errors` is a list of {"path", "message"} like a scene's."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Check(_Model):
    """One test on the submitted scene (after validation, so defaults are filled in).

    Either `count` (how many materials, lights, objects or primitives match `where`) or `value`
    (a field of the scene by its path, e.g. "render.max_depth"), compared with the given words."""

    count: Literal["materials", "lights", "objects", "primitives"] | None = Field(
        None, description="Count these (materials: those the objects use, named or inline; primitives: "
        "shapes plus triangles, a box being 12)."
    )  # fmt: skip
    where: dict[str, Any] = Field(
        default_factory=dict,
        description='Only count items whose fields pass: {"kt": {"greater_than": 0}, "type": "quad"} '
        '(a bare value means equals; {"present": true}: set and not zero/empty).',
    )
    value: str | None = Field(None, description="A field of the scene by path, e.g. 'camera.lens_radius'.")
    equals: Any = None
    at_least: float | None = None
    at_most: float | None = None
    greater_than: float | None = None
    less_than: float | None = None
    one_of: list | None = None

    @model_validator(mode="after")
    def _one_kind(self) -> Check:
        if (self.count is None) == (self.value is None):
            raise ValueError("give exactly one of 'count' (a number of things) or 'value' (a field of the scene)")
        if self.value is not None and self.where:
            raise ValueError("'where' goes with 'count', not with 'value'")
        if not self.comparisons():
            raise ValueError(f"give at least one comparison: {', '.join(COMPARISONS)}")
        for key, test in self.where.items():
            for word in test if isinstance(test, dict) else ():
                if word not in COMPARISONS and word != "present":
                    words = ", ".join([*COMPARISONS, "present"])
                    raise ValueError(f"where.{key}: unknown comparison '{word}' (use {words})")
        return self

    def comparisons(self) -> dict[str, Any]:
        return {w: getattr(self, w) for w in COMPARISONS if getattr(self, w) is not None}


class Requirement(_Model):
    name: str = Field(min_length=1, description="Shown to the student, e.g. 'a glass object'.")
    points: float = Field(ge=0, description="Earned when the check passes.")
    description: str | None = Field(None, description="Longer text for the student.")
    check: Check = Field(description="A check object, or the name of a preset: " + ", ".join(PRESETS))

    @field_validator("check", mode="before")
    @classmethod
    def _preset(cls, v: Any) -> Any:
        if isinstance(v, str):
            if v not in PRESETS:
                close = difflib.get_close_matches(v, list(PRESETS), n=1, cutoff=0.6)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise ValueError(f"unknown preset '{v}'{hint} (the presets: {', '.join(PRESETS)})")
            return dict(PRESETS[v])
        return v


class RenderOverrides(_Model):
    """Settings every render of the assignment uses (the submission's own are replaced)."""

    width: int | None = Field(None, ge=1, le=4096, description="Film width; default: the reference scene's.")
    height: int | None = Field(None, ge=1, le=4096, description="Film height; default: the reference scene's.")
    spp: int | None = Field(None, ge=1, description="Samples per pixel; default: the submission's own (limited).")
    seed: int = Field(7, ge=0, lt=2**31, description="The seed of every submission's render.")
    sampler: SamplerType | None = None
    integrator: IntegratorName | None = None
    max_depth: int | None = Field(None, ge=1, le=64)


class GradingLimits(_Model):
    """Per student: a submission past one of these is invalid (with the field named), and a render
    that runs longer than `max_seconds` is stopped (its image tests score 0). Each max_* is a limit of
    the table in tracer/limits.py, tighter by default than the service's."""

    max_seconds: float = Field(60.0, gt=0, le=3600, description="Seconds one render may take.")
    max_width: int = Field(1024, ge=1)
    max_height: int = Field(1024, ge=1)
    max_pixels: int = Field(1024 * 1024, ge=1)
    max_spp: int = Field(256, ge=1)
    max_depth: int = Field(16, ge=1, le=64)
    max_light_samples: int = Field(16, ge=1)
    max_primitives: int = Field(100_000, ge=1)

    def scene_limits(self) -> Limits:
        """The scene limits of a student's render: these, and the table's defaults for the others."""
        return Limits(**{name: getattr(self, name) for name in LIMIT_NAMES if name in type(self).model_fields})


class Validity(_Model):
    points: float = Field(1.0, ge=0, description="Earned by a scene that validates.")
    per_error: float | None = Field(
        None, ge=0, description="Points lost per error (default: all of them for any error)."
    )


class FlipTest(_Model):
    points: float = Field(ge=0)
    margin: float = Field(0.02, ge=0, description="Pass: mean FLIP <= noise baseline + margin.")
    limit: float | None = Field(None, ge=0, le=1, description="Pass: mean FLIP <= limit (instead of the margin).")


class SsimTest(_Model):
    points: float = Field(ge=0)
    margin: float = Field(0.03, ge=0, description="Pass: SSIM >= noise baseline - margin.")
    limit: float | None = Field(None, ge=-1, le=1, description="Pass: SSIM >= limit (instead of the margin).")


class PsnrTest(_Model):
    points: float = Field(ge=0)
    margin: float = Field(2.0, ge=0, description="Pass: PSNR >= noise baseline - margin (dB).")
    limit: float | None = Field(None, ge=0, description="Pass: PSNR >= limit dB (instead of the margin).")


class PixelTest(_Model):
    points: float = Field(ge=0)
    alpha: float = Field(1e-3, gt=0, lt=0.5, description="Per-pixel false-alarm rate of the z test.")
    max_fraction: float = Field(0.01, ge=0, le=1, description="Pass: at most this share of pixels rejected.")


class ProbeSpec(_Model):
    """A pixel the instructor wants every student's tree log to show (docs/own-tracer.md)."""

    x: int = Field(ge=0, description="Column, from the left.")
    y: int = Field(ge=0, description="Row, from the top.")
    why: str | None = Field(None, max_length=200, description="Shown to the student: what this pixel shows.")


class Reference(_Model):
    """The picture the submissions should match: a scene, rendered by us."""

    scene: str | dict = Field(description="The reference scene, inline or a file beside the assignment.")
    spp: int = Field(256, ge=1, le=65536, description="Samples per pixel of the reference mean (and variance).")
    seed: int = Field(1_000_003, ge=0, lt=2**31 - 2, description="Seed of the reference mean; +1: the noise baseline.")
    flip: FlipTest | None = None
    ssim: SsimTest | None = None
    psnr: PsnrTest | None = None
    pixels: PixelTest | None = None
    probes: list[ProbeSpec] = Field(default_factory=list, max_length=16, description="Pixels every student's "
                                    "tree log should show, beside the probes found in their error map.")  # fmt: skip


class ImageSettings(_Model):
    """Grading a student's own image of the reference scene."""

    spp: int | None = Field(None, ge=1, description="Samples per pixel the students were told to use "
                            "(default: the assignment's render.spp, else the reference scene's).")  # fmt: skip


MAX_LEVELS = 9  # rubric levels of a manual item: keys 1..9 on the grading queue


class RubricLevel(_Model):
    """One level (a checkable criterion) of a manual item's rubric."""

    name: str = Field(min_length=1, max_length=100, description="Shown to graders and the student, e.g. 'glass'.")
    points: float = Field(description="Added when chosen (negative: a deduction); within -points..points of its item.")
    description: str | None = Field(None, max_length=1000, description="What earns it, for graders and students.")


class ManualItem(_Model):
    """A part of the grade that staff give by hand (docs/grading.md, "Staff-graded items")."""

    name: str = Field(min_length=1, max_length=100, description="The item, e.g. 'an interesting scene'.")
    points: float = Field(gt=0, description="The most it is worth: its chosen levels' sum is clamped to 0..points.")
    rubric: list[RubricLevel] = Field(min_length=1, max_length=MAX_LEVELS)
    instructions: str | None = Field(None, max_length=4000, description="For the graders.")

    def level(self, name: str) -> RubricLevel | None:
        return next((r for r in self.rubric if r.name == name), None)

    def score(self, chosen: list[str]) -> float:
        """The chosen levels' points (by name; a name no longer in the rubric counts nothing), clamped."""
        total = sum(r.points for r in self.rubric if r.name in set(chosen))
        return min(self.points, max(0.0, total))


def _manual_errors(items: list[ManualItem]) -> list[dict]:
    """What pydantic cannot say of manual items, at their paths: names unique, a level's points in range."""
    errors, names = [], set()
    for i, item in enumerate(items):
        if item.name in names:
            message = f"a second item named {item.name!r}: names are unique"
            errors.append({"path": f"manual[{i}].name", "message": message})
        names.add(item.name)
        levels = set()
        for j, level in enumerate(item.rubric):
            at = f"manual[{i}].rubric[{j}]"
            if level.name in levels:
                errors.append({"path": f"{at}.name", "message": f"a second level named {level.name!r} in this item"})
            levels.add(level.name)
            if abs(level.points) > item.points:
                message = f"expected points within -{item.points:g}..{item.points:g} (the item's); got {level.points:g}"
                errors.append({"path": f"{at}.points", "message": message})
    return errors


class Assignment(_Model):
    version: Literal[1] = 1
    name: str = Field(min_length=1, description="Shown in reports, e.g. 'HW 4: glass and soft shadows'.")
    description: str | None = None
    render: RenderOverrides = Field(default_factory=RenderOverrides)
    limits: GradingLimits = Field(default_factory=GradingLimits)
    validity: Validity = Field(default_factory=Validity)
    requirements: list[Requirement] = Field(default_factory=list)
    reference: Reference | None = None
    image: ImageSettings = Field(default_factory=ImageSettings)
    manual: list[ManualItem] = Field(default_factory=list, max_length=50, description="Items graded by staff.")

    def manual_points(self) -> float:
        """The most the staff-graded items are worth together (not part of `max_score`: the autograder's)."""
        return sum(m.points for m in self.manual)

    def manual_item(self, name: str) -> ManualItem | None:
        return next((m for m in self.manual if m.name == name), None)

    def max_score(self, kind: str = "scene") -> float:
        """The most a submission of this kind can earn: a scene every test's points; an image (png, exr) its
        validity's ("readable image") and the image tests' (the requirements are checks of a scene)."""
        total = self.validity.points + sum(t.points for t in self.image_tests().values())
        if kind == "scene":
            total += sum(r.points for r in self.requirements)
        return total

    def max_scores(self) -> dict[str, float]:
        """{"scene": ..., "image": ...}: the maximum of each kind of submission (`max_score`)."""
        return {kind: self.max_score(kind) for kind in ("scene", "image")}

    def image_tests(self) -> dict[str, FlipTest | SsimTest | PsnrTest | PixelTest]:
        ref = self.reference
        if ref is None:
            return {}
        return {k: t for k in ("flip", "ssim", "psnr", "pixels") if (t := getattr(ref, k)) is not None}


def load_assignment(src: Any) -> tuple[Assignment, Path | None]:
    """A Path to a JSON file, JSON text or a dict -> (Assignment, the folder its files are relative to).
    Raises AssignmentError with every error at its JSON path."""
    base = None
    if isinstance(src, Path):
        base = src.resolve().parent
        try:
            src = src.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise AssignmentError([{"path": "", "message": f"cannot read assignment file: {e}"}]) from None
    if isinstance(src, bytes | str):
        try:
            src = json.loads(src)
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            where = f" at line {e.lineno}, column {e.colno}" if isinstance(e, json.JSONDecodeError) else ""
            raise AssignmentError([{"path": "", "message": f"invalid JSON{where}: {e}"}]) from None
    if not isinstance(src, dict):
        raise AssignmentError([{"path": "", "message": "an assignment must be a JSON object {...}"}])
    try:
        assignment = Assignment.model_validate(src)
    except ValidationError as e:
        raise AssignmentError(pydantic_errors(e, Assignment)) from None
    errors = _manual_errors(assignment.manual)
    if errors:
        raise AssignmentError(errors)
    return assignment, base
