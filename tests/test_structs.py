"""The kernels' shared data types (tracer/structs.py) and the shape of the package they make possible:
no import cycle anywhere under tracer/, and the library never imports the service."""

from __future__ import annotations

import ast
import subprocess
import sys

from conftest import ROOT

TRACER = ROOT / "tracer"


def module_name(path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(TRACER.rglob("*.py"))}


def imports_of(name: str) -> set[str]:
    """Every module `name` imports, at the top or inside a function (a lazy import is still a dependency):
    `from tracer.kinds import End` names the module, `from tracer.integrators import record` the submodule
    alone (a package's __init__ runs first in any case)."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package up
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            subs = {f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES}
            out |= subs if len(subs) == len(node.names) else {base, *subs}
    return out


def graph() -> dict[str, set[str]]:
    """Edges between tracer's own modules."""
    return {m: {i for i in imports_of(m) if i in MODULES and i != m} for m in MODULES}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_structs_the_package_has_no_import_cycle():
    assert cycles(graph()) == []


def test_structs_the_cycle_finder_finds_one():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_structs_the_library_never_imports_the_service():
    offenders = {m: sorted(i for i in imports_of(m) if i == "server" or i.startswith("server.")) for m in MODULES}
    assert {m: i for m, i in offenders.items() if i} == {}


def test_structs_depend_on_nothing_of_the_renderer():
    """Everything else imports the kernels' data types; they import only Warp's initialisation."""
    assert graph()["tracer.structs"] == {"tracer.wpinit"}


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
    from tracer.structs import SceneData

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
