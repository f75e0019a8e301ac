"""The one table that names the integrators (their kernels are the modules of tracer/integrators/).

`INTEGRATORS` is the only list of them: the scene format's `render.integrator` values, the
assignment spec's, the `Integrator` enum of tracer/kernels/kinds.py, the kernel table of
tracer/integrators/dispatch.py and the JSON Schema's `x-integrators` all come from it. What else differs
between integrators is a column of the table too: what must be solved before the render (`prepass`) and
how the render's cost is estimated (`cost`), so no code outside this table names an integrator. A new
integrator is a module with a `trace` in tracer/integrators/ and one line below. This module imports
nothing, so the scene's models and the kernels' kinds can read the table without Warp and without the
integrators (it sits in scene/, the lowest of the packages: tests/tracer/test_layers.py).
"""

from typing import NamedTuple


class IntegratorInfo(NamedTuple):
    name: str  # the scene's render.integrator
    kernels: str  # the module under tracer/integrators/ whose `trace` its kernels run
    description: str  # one line, for the JSON Schema and the docs
    prepass: str | None  # what is solved before the render: "radiosity" (tracer/radiosity/), or None
    cost: str  # how tracer/rendering/estimate.py counts a sample's rays: "tree" (a ray tree's nodes), "path" (bounces)


INTEGRATORS = (
    IntegratorInfo(
        "whitted",
        "whitted",
        "The recursive ray tree of Whitted (1980) with Phong shading; with area lights, a lens, a shutter or "
        "glossy materials it is distribution ray tracing (Cook et al. 1984).",
        None,
        "tree",
    ),
    IntegratorInfo(
        "path",
        "path",
        "Path tracing (Kajiya 1986): diffuse interreflection, next-event estimation with multiple importance "
        "sampling, Russian roulette.",
        None,
        "path",
    ),
    IntegratorInfo(
        "radiosity",
        "whitted",
        "Radiosity by progressive refinement (Cohen et al. 1988), solved before the render and shown through "
        "the ray tree (two-pass) or as its patches.",
        "radiosity",
        "tree",
    ),
)
NAMES = tuple(i.name for i in INTEGRATORS)
BY_NAME = {i.name: i for i in INTEGRATORS}  # a scene's render.integrator -> its row (SceneData.integrator: its index)
