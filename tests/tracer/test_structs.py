"""The kernels' shared data types (tracer/kernels/structs.py) and the shape of the package they make possible:
no import cycle anywhere under tracer/, and the library never imports the service."""

from __future__ import annotations

import subprocess
import sys

from tests.support.layering import cycles, imports_of, modules
from tests.support.layering import graph as package_graph
from tests.support.scene import ROOT

MODULES = modules("tracer")


def graph() -> dict[str, set[str]]:
    """Edges between tracer's own modules."""
    return package_graph("tracer")


def test_structs_the_package_has_no_import_cycle():
    assert cycles(graph()) == []


def test_structs_the_cycle_finder_finds_one():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_structs_the_library_never_imports_the_service():
    def of_service(m: str) -> list[str]:
        return sorted(i for i in imports_of(m, MODULES) if i == "server" or i.startswith("server."))

    assert {m: i for m in MODULES if (i := of_service(m))} == {}


def test_structs_depend_on_nothing_of_the_renderer():
    """Everything else imports the kernels' data types; they import only Warp's initialisation."""
    assert graph()["tracer.kernels.structs"] == {"tracer.kernels.wpinit"}


def test_structs_every_module_imports_in_a_fresh_interpreter():
    """Every module of tracer/ imported into a fresh interpreter, and nothing of the service comes along."""
    code = (
        "import importlib, sys\n"
        "for name in sys.argv[1:]:\n"
        "    importlib.import_module(name)\n"
        "assert not [m for m in sys.modules if m == 'server' or m.startswith('server.')], 'server imported'\n"
    )
    p = subprocess.run([sys.executable, "-c", code, *MODULES], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]


def test_structs_go_to_inlined_helpers_only():
    """Warp passes a struct to a @wp.func by value, so every helper that takes one is inlined: a SceneData
    is about 1.7 KB, and copying it at every call made the Whitted kernel 1.4x slower (BENCHMARKS.md)."""
    import importlib

    from tracer.integrators.common import max3
    from tracer.kernels.structs import SceneData

    function, struct = type(max3), type(SceneData)
    copied = []
    for name in MODULES:
        if name == "tracer.__main__":
            continue
        for f in vars(importlib.import_module(name)).values():
            if isinstance(f, function) and f.func.__module__ == name:
                takes = [k for k, t in f.input_types.items() if isinstance(t, struct)]
                if takes and f.inline_hint != "forceinline":
                    copied.append(f"{name}.{f.func.__name__}({', '.join(takes)})")
    assert copied == []
