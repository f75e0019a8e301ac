"""The integrators, and the one table that names them.

Each integrator is a module here with one ``trace`` @wp.func, all with the same signature:

    trace(scene, o, d, time, rng, key, sample, st, row, record, rec) -> SampleOut

the eye ray (o, d) at shutter time `time`; the pixel sample's random state `rng`, its pixel's
low-discrepancy `key` and its index `sample` (sampling.sample_2d); the per-thread `Stack` (st, row)
for integrators that keep pending rays; and the ray-tree record (record = 1: write every ray into
rec, record.py). dispatch.py wraps each `trace` in the render kernels.

`INTEGRATORS` is the only list of them: the scene format's `render.integrator` values, the
assignment spec's, the `Integrator` enum of tracer/kernels/kinds.py, the kernel table of dispatch.py and the
JSON Schema's `x-integrators` all come from it. What else differs between integrators is a column of
the table too: what must be solved before the render (`prepass`) and how the render's cost is estimated
(`cost`), so no code outside this table names an integrator. A new integrator is a module with a `trace`
and one line below. This module imports nothing, so the scene's models can read the table without Warp.
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
