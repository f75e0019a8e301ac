"""The library's shape (tracer/): its packages in layers, each module importing only from its own package and the
layers below it, as server/'s are (tests/server/test_layers.py). Type-only imports count too. The order, lowest
first: the base modules (errors, limits, assets, meshing), the scene format with the integrators' table, the
Warp side every kernel shares (and the scene compiled into it), radiosity, the integrators (whose Whitted reads a
radiosity solution), a render run, the tools around the renderer, grading; the command line on top."""

from __future__ import annotations

from tests.support.layering import LazyGraph

TRACER = LazyGraph("tracer")  # every import, those made only for type checkers too
TOP = {"tracer", "tracer.__main__"}  # the package and the command line: anything
LAYERS = (  # lowest first: a module may import its own layer's and those listed before it
    "tracer.errors",  # SceneError, pydantic's errors as {path, message}
    "tracer.limits",  # the table of scene limits
    "tracer.assets",  # mesh and image files, data: URIs
    "tracer.meshing",  # shapes in plain numpy, the radiosity patches counted
    "tracer.scene",  # the scene format's models; the integrators' table (scene/integrators.py)
    "tracer.kernels",  # Warp's structs, kinds, @wp.func helpers; the scene compiled into them, launches in bands
    "tracer.radiosity",  # patches, the solver, its cache, the solution's lookup at a hit
    "tracer.integrators",  # each integrator's trace, the render kernels made from them
    "tracer.rendering",  # a render run: progressive passes, ray trees, the film, the cost estimate
    "tracer.tools",  # bench, the scene docs, pixel samples, JSON positions, spreadsheet cells
    "tracer.grading",  # assignments, checks, metrics, reports, a student's own tracer explained
)


def layer(module: str) -> int | None:
    return next((k for k, p in enumerate(LAYERS) if module == p or module.startswith(p + ".")), None)


def allowed(module: str, imported: str) -> bool:
    own, other = layer(module), layer(imported)
    return own is None or (other is not None and other <= own)


def test_layers_every_module_of_the_library_is_in_a_layer_or_at_the_top():
    assert [m for m in TRACER if layer(m) is None and m not in TOP] == []


def test_layers_each_package_of_the_library_imports_only_itself_and_the_layers_below():
    offenders = {m: sorted(i for i in deps if not allowed(m, i)) for m, deps in TRACER.items()}
    assert {m: i for m, i in offenders.items() if i} == {}


def test_layers_the_library_rule_catches_an_import_that_goes_up():
    # the imports of before: the kernels' kinds read the integrators' table, radiosity compiled with rendering's
    assert not allowed("tracer.kernels.kinds", "tracer.integrators")
    assert not allowed("tracer.radiosity.solver", "tracer.rendering.compile")
    assert not allowed("tracer.scene.render", "tracer.integrators")
    assert not allowed("tracer.kernels.compile", "tracer.rendering.film")
    assert not allowed("tracer.scene", "tracer.server_like_unknown")  # an unknown module is no layer below
    assert allowed("tracer.integrators.whitted", "tracer.radiosity.lookup")
    assert allowed("tracer.kernels.lights", "tracer.scene")
    assert allowed("tracer.__main__", "tracer.grading")


def test_layers_the_integrators_table_is_read_below_the_integrators():
    """The scene's models and the kernels' Integrator enum name the integrators from the table alone (plain data in
    scene/), never from the package of their kernels."""
    assert TRACER["tracer.scene.integrators"] == set()
    assert "tracer.scene.integrators" in TRACER["tracer.kernels.kinds"]
    assert "tracer.scene.integrators" in TRACER["tracer.scene.render"]
