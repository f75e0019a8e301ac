"""The import graph of a package of this repository, read from its sources (nothing is imported): what each
module imports, at the top or inside a function (a lazy import is still a dependency), and the imports made only
for type checkers (`if TYPE_CHECKING:`) as well unless `typing=False`: a cycle that only a type-only import
closes is still two modules that cannot be read or changed apart (it hid grading's run <-> runs); and the import
cycles in it (Tarjan)."""

from __future__ import annotations

import ast
import functools
from collections.abc import Iterator, Mapping
from pathlib import Path

from tests.support.scene import ROOT


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(package: str) -> dict[str, Path]:
    """Every module of the package (tracer, server), by its dotted name."""
    return {module_name(p): p for p in sorted((ROOT / package).rglob("*.py"))}


def _typing_only(tree: ast.AST) -> set[int]:
    """The ids of the import nodes under an `if TYPE_CHECKING:` (never run: no dependency at run time)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", None)) == "TYPE_CHECKING":
            out |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return out


def imports_of(name: str, known: dict[str, Path], typing: bool = True) -> set[str]:
    """Every module `name` imports: `from tracer.kernels.kinds import End` names the module, `from tracer.integrators
    import record` the submodule alone (a package's __init__ runs first in any case). `typing=False`: only those
    imported at run time (not under `if TYPE_CHECKING:`)."""
    path = known[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    skip = set() if typing else _typing_only(tree)
    out = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package up
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            subs = {f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known}
            out |= subs if len(subs) == len(node.names) else {base, *subs}
    return out


@functools.cache
def graph(package: str, typing: bool = True) -> dict[str, set[str]]:
    """Edges between the package's own modules (`typing=False`: those of run-time imports only), read once per
    process (the same dict each time: a caller must not change it)."""
    known = modules(package)
    return {m: {i for i in imports_of(m, known, typing) if i in known and i != m} for m in known}


class LazyGraph(Mapping):
    """`graph(package, typing)`, read at its first use: a test module's constant that costs nothing at collection
    (every pytest process imports every test module; only the one that runs its tests reads the sources)."""

    def __init__(self, package: str, typing: bool = True):
        self.package, self.typing = package, typing

    def _edges(self) -> dict[str, set[str]]:
        return graph(self.package, self.typing)

    def __getitem__(self, module: str) -> set[str]:
        return self._edges()[module]

    def __iter__(self) -> Iterator[str]:
        return iter(self._edges())

    def __len__(self) -> int:
        return len(self._edges())


def cycles(edges: Mapping[str, set[str]]) -> list[list[str]]:
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
