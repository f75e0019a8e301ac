"""Integrators by registry name: each module gives a render kernel and a ray-tree kernel."""

from tracer.integrators import whitted

INTEGRATORS = {"whitted": whitted}
