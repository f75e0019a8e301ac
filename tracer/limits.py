"""The scene limits: one table, from which every set of them is made.

A scene past a limit is an error at the offending field's JSON path ("must be at most 2048 (limit
max_width)"), the same through the command line, the service and grading. One limit is a bound the
kernels keep instead: `max_tree_rays`, the rays of one pixel sample's ray tree (Whitted's tree doubles with
each level where a material both reflects and transmits: with max_depth 64 and min_weight 0 nothing else
ends it). A ray past it is not traced, the same in the image and in the ray tree, which shows the cut as
the end reason `max_tree_rays`; tracer/rendering/estimate.py counts a sample's rays up to it. The table below is the
one definition of the limits (name, default, what is counted):

- `Limits`, the dataclass the validators read (tracer/scene/), is made from it, its defaults the table's;
- the service's settings TRACER_MAX_WIDTH, ... (server/core/settings.py) are its rows, with the same defaults
  and descriptions (docs/service.md lists them);
- an assignment's limits (tracer/grading/spec.py, `GradingLimits`) tighten some of them for its students,
  and a grading render takes the tighter of the assignment's and the service's (`Limits.tighter`).

This module imports nothing of the tracer, so the service's settings can read it without the scene models.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

PILLOW_MAX_PIXELS = 89_478_485  # Pillow warns of a decompression bomb past this (PIL.Image.MAX_IMAGE_PIXELS)


class LimitInfo(NamedTuple):
    name: str  # the field of Limits, and the setting TRACER_ + the name in capitals
    default: int  # the library's and the service's default
    description: str  # what is counted, in which unit (the setting's description)
    most: int | None = None  # the largest value the setting may be given (None: any); every limit is >= 1


LIMITS = (
    LimitInfo("max_width", 2048, "image width (pixels)"),
    LimitInfo("max_height", 2048, "image height (pixels)"),
    LimitInfo("max_pixels", 2048 * 2048, "width x height"),
    LimitInfo("max_spp", 4096, "samples per pixel"),
    LimitInfo("max_depth", 64, "render.max_depth"),
    LimitInfo("max_light_samples", 256, "render.light_samples"),
    LimitInfo("max_primitives", 2_000_000, "shapes plus mesh triangles (mesh files included)"),
    # Images, counted from their headers before any is decoded; a decoded pixel is 12 bytes (float32 RGB)
    LimitInfo(
        "max_texture_pixels",
        4096 * 4096,
        "width x height of one texture or bump image (read from its header, before any pixel is decoded; a "
        "decoded pixel is 12 bytes)",
        most=PILLOW_MAX_PIXELS,
    ),
    LimitInfo(
        "max_texture_pixels_total",
        4096 * 4096,
        "width x height summed over every distinct image of a scene (textures and bump maps, files and data: "
        "URIs), from their headers: at the default, 192 MiB of decoded pixels per scene",
    ),
    # The radiosity solve, counted before anything is meshed or shot (tracer/meshing.py)
    LimitInfo(
        "max_patches",
        100_000,
        "radiosity: pieces of surface (two sides each) that render.radiosity.patch_size cuts a scene into, "
        "counted from the geometry before anything is meshed",
    ),
    LimitInfo(
        "max_solve_rays",
        250_000_000,
        "radiosity: render.radiosity.rays x max_steps, the form-factor rays of the longest solve",
    ),
    # Not checked at validation: the kernels enforce it, as the end reason max_tree_rays of the ray tree
    LimitInfo(
        "max_tree_rays",
        1024,
        "eye, reflection and transmission rays of one pixel sample's ray tree (its shadow rays come on top): a "
        "wanted ray past it is not traced, and the ray tree shows where (end max_tree_rays)",
    ),
)
NAMES = tuple(limit.name for limit in LIMITS)


def _tighter(self: Limits, other: Limits) -> Limits:
    """The smaller of the two, limit by limit (an assignment's within the service's)."""
    return Limits(**{name: min(getattr(self, name), getattr(other, name)) for name in NAMES})


def _at_most(self: Limits, name: str) -> str:
    """The message of a value past the limit `name`: 'must be at most 2048 (limit max_width)'."""
    return f"must be at most {getattr(self, name)} (limit {name})"


if TYPE_CHECKING:

    class Limits:
        """What the checker sees of the class made below from the table LIMITS: one int field per limit."""

        __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

        def __init__(self, **limits: int) -> None: ...
        def __getattr__(self, name: str) -> int: ...
        def tighter(self, other: Limits) -> Limits: ...
        def at_most(self, name: str) -> str: ...

else:
    Limits = dataclasses.make_dataclass(
        "Limits",
        [(limit.name, int, limit.default) for limit in LIMITS],
        frozen=True,
        namespace={
            "__doc__": "Scene limits (the table LIMITS); a value past one is an error at its JSON path.",
            "__module__": __name__,
            "tighter": _tighter,
            "at_most": _at_most,
        },
    )
