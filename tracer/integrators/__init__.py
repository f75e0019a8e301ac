"""The integrators: each a module here with one ``trace`` @wp.func, all with the same signature:

    trace(scene, o, d, time, rng, key, sample, st, row, record, rec) -> SampleOut

the eye ray (o, d) at shutter time `time`; the pixel sample's random state `rng`, its pixel's
low-discrepancy `key` and its index `sample` (sampling.sample_2d); the per-thread `Stack` (st, row)
for integrators that keep pending rays; and the ray-tree record (record = 1: write every ray into
rec, record.py). dispatch.py wraps each `trace` in the render kernels.

The table that names them (`INTEGRATORS`) is tracer/scene/integrators.py, below this package: the scene's
models and the kernels' `Integrator` enum read it without importing any integrator. A new integrator is a
module here with a `trace` and one line in that table.
"""
