"""Radiosity by progressive refinement with ray-cast form factors (Goral et al. 1984; Cohen et al. 1988).

Every surface is cut into patches (`patches.py`); the patch (or light) with the most unshot power shoots
it, its form factors estimated by casting rays (`solver.py`, the rays in `form_factors.py`); the solution is
made ready for the image (`display.py`: corner values for the smooth display, `attach`) and kept on disk
by content (`cache.py`). The integrators read it at a hit through `lookup.py`'s @wp.func alone, so an
integrator's kernels need nothing else of this package.

Units: radiosity B is exitance, W/m^2; the radiance a diffuse patch sends out is B / pi.

The names below are this package's public ones, each imported from its module when first asked for:
`from tracer import radiosity` costs nothing until `radiosity.attach` (or any other) is used, so a render
that needs no solution never loads the solver.
"""

from __future__ import annotations

import importlib

PUBLIC = {
    "tracer.radiosity.patches": (
        "DISK_MIN_SECTORS",
        "SPHERE_MIN_SEGMENTS",
        "Patches",
        "build_patches",
        "check_limits",
        "disk_net",
        "patch_index",
        "solid_angle",
        "sphere_net",
        "triangles",
    ),
    "tracer.radiosity.lookup": ("SPHERE_REACH", "patch_at", "radiosity_ambient", "radiosity_at", "safe_div"),
    "tracer.radiosity.form_factors": ("TARGET_ESCAPED", "TARGET_LIGHT", "direct", "shoot"),
    "tracer.radiosity.solver": ("LIGHT_RAYS_PER_PATCH", "SNAPSHOT_EVERY_STEP", "Solution", "solve"),
    "tracer.radiosity.display": ("attach", "corner_values"),
    "tracer.radiosity.cache": ("PATCH_FIELDS", "SolutionCache"),
    "tracer.errors": ("Cancelled",),  # what a cancelled solve raises
}  # the module that defines each public name
HOME = {name: module for module, names in PUBLIC.items() for name in names}
__all__ = sorted(HOME)


def __getattr__(name: str):
    """A public name, imported from its module on first use (PEP 562)."""
    if name not in HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(HOME[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
