"""Named kinds shared by Python and the Warp kernels.

Each kind is a Python ``IntEnum`` (for the compiler, the ray-tree JSON and tests) mirrored by
``wp.constant`` values (for kernels), so no kernel ever compares against a magic number. Two kinds
are derived from tables elsewhere: `Integrator` from tracer/scene/integrators.py, and the light
kinds (tracer/kernels/lights.py) from the scene format's light types.
"""

from enum import IntEnum
from typing import cast

import warp as wp

from tracer.kernels import wpinit  # noqa: F401  (initialise Warp once)
from tracer.scene.integrators import INTEGRATORS


class Shape(IntEnum):
    """Analytic primitives kept in the shape list (triangles live in one wp.Mesh)."""

    SPHERE = 0
    PLANE = 1
    QUAD = 2
    DISK = 3
    BOX = 4


class Texture(IntEnum):
    NONE = 0
    CHECKER = 1
    IMAGE = 2


class Bump(IntEnum):
    NONE = 0
    NOISE = 1
    IMAGE = 2


class RayKind(IntEnum):
    EYE = 0
    SHADOW = 1
    REFLECTION = 2
    TRANSMISSION = 3


class End(IntEnum):
    """Why a ray of the tree has fewer children than a reflection and a transmission ray."""

    NONE = 0
    MISS = 1
    MAX_DEPTH = 2
    MIN_WEIGHT = 3
    TIR = 4
    LIGHT = 5
    ABSORBED = 6
    MAX_TREE_RAYS = 7  # a wanted child was not traced: the sample's tree had its max_tree_rays rays (limits.py)


# The integrators of the table in tracer/scene/integrators.py, numbered in its order (SceneData.integrator).
# Made from the table at run time, so pyright cannot list its members: the cast says it is an IntEnum class.
Integrator = cast(
    type[IntEnum], IntEnum("Integrator", [(i.name.upper(), k) for k, i in enumerate(INTEGRATORS)], module=__name__)
)


class FilterKind(IntEnum):
    BOX = 0
    TENT = 1
    GAUSSIAN = 2
    MITCHELL = 3


class SamplerKind(IntEnum):
    CENTER = 0
    GRID = 1
    RANDOM = 2
    JITTERED = 3
    ADAPTIVE = 4
    LOWDISCREPANCY = 5


class PatchKind(IntEnum):
    """How the radiosity patches of an object are found from a point on it (tracer/radiosity/lookup.py)."""

    NONE = 0  # not meshed (an object the solve cannot see)
    FLAT = 1  # flat facets: the nearest facet to the point
    SPHERE = 2  # facets inscribed in a sphere: the facet the ray from the centre through the point crosses
    DISK = 3  # facets inscribed in a disk: the nearest facet to the point pulled inside their polygon


class RadDisplay(IntEnum):
    """What the radiosity integrator shows (render.radiosity.display)."""

    TWO_PASS = 0  # the ray tree, with the solution's interreflection in place of the ambient term
    FLAT = 1  # each patch's own radiosity
    SMOOTH = 2  # radiosity interpolated from the patch corners


class Shooter(IntEnum):
    """Who shoots power in a step of progressive refinement."""

    PATCH = 0  # a patch side (a parallelogram or a triangle; on a sphere, projected onto it)
    LIGHT = 1  # an area light, sampled over its surface


SHAPE_SPHERE = wp.constant(int(Shape.SPHERE))
SHAPE_PLANE = wp.constant(int(Shape.PLANE))
SHAPE_QUAD = wp.constant(int(Shape.QUAD))
SHAPE_DISK = wp.constant(int(Shape.DISK))
SHAPE_BOX = wp.constant(int(Shape.BOX))

PATCHES_NONE = wp.constant(int(PatchKind.NONE))
PATCHES_FLAT = wp.constant(int(PatchKind.FLAT))
PATCHES_SPHERE = wp.constant(int(PatchKind.SPHERE))
PATCHES_DISK = wp.constant(int(PatchKind.DISK))

RAD_TWO_PASS = wp.constant(int(RadDisplay.TWO_PASS))
RAD_FLAT = wp.constant(int(RadDisplay.FLAT))
RAD_SMOOTH = wp.constant(int(RadDisplay.SMOOTH))

SHOOT_PATCH = wp.constant(int(Shooter.PATCH))
SHOOT_LIGHT = wp.constant(int(Shooter.LIGHT))

FILTER_BOX = wp.constant(int(FilterKind.BOX))

TEX_NONE = wp.constant(int(Texture.NONE))
TEX_CHECKER = wp.constant(int(Texture.CHECKER))
TEX_IMAGE = wp.constant(int(Texture.IMAGE))

BUMP_NONE = wp.constant(int(Bump.NONE))
BUMP_NOISE = wp.constant(int(Bump.NOISE))
BUMP_IMAGE = wp.constant(int(Bump.IMAGE))

RAY_EYE = wp.constant(int(RayKind.EYE))
RAY_SHADOW = wp.constant(int(RayKind.SHADOW))
RAY_REFLECTION = wp.constant(int(RayKind.REFLECTION))
RAY_TRANSMISSION = wp.constant(int(RayKind.TRANSMISSION))

END_NONE = wp.constant(int(End.NONE))
END_MISS = wp.constant(int(End.MISS))
END_MAX_DEPTH = wp.constant(int(End.MAX_DEPTH))
END_MIN_WEIGHT = wp.constant(int(End.MIN_WEIGHT))
END_TIR = wp.constant(int(End.TIR))
END_LIGHT = wp.constant(int(End.LIGHT))
END_ABSORBED = wp.constant(int(End.ABSORBED))
END_MAX_TREE_RAYS = wp.constant(int(End.MAX_TREE_RAYS))

SAMPLER_CENTER = wp.constant(int(SamplerKind.CENTER))
SAMPLER_GRID = wp.constant(int(SamplerKind.GRID))
SAMPLER_RANDOM = wp.constant(int(SamplerKind.RANDOM))
SAMPLER_ADAPTIVE = wp.constant(int(SamplerKind.ADAPTIVE))
SAMPLER_LOWDISCREPANCY = wp.constant(int(SamplerKind.LOWDISCREPANCY))

# Spawned rays start at hit + RAY_OFFSET * N (docs/scene-format.md, "Where spawned rays start"): part of the contract.
RAY_OFFSET = wp.constant(1.0e-4)
# Nothing in a scene is farther than this (world units); a ray that reaches it left the scene.
T_FAR = wp.constant(1.0e30)
