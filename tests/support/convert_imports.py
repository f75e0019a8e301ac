"""Rewrites the tests' old bare imports of helpers (before tests/ was a package) to the `tests.support` package,
and the imports of the library's modules that moved when tracer/ was layered (issue #40).

    .venv/bin/python tests/support/convert_imports.py [FILE_OR_FOLDER ...]    (default: tests/)

`from conftest import ROOT` becomes `from tests.support.scene import ROOT`, `from test_api_support import Server`
`from tests.support.api import Server`, `from test_web_page import Page` `from tests.support.page import Page`, and so
on (the table below); a name imported from another test module goes to the support module that now holds it, or, if
none does, to the test module's dotted name (`tests.server.course.test_x`), with a warning: move such a helper to
tests/support/ by hand. `import test_lms` and `tool = test_lms.tool` (fixtures taken from another module) are
reported, not rewritten: the fixtures `tool` and `lms` are registered by tests/server/course/ and tests/web/'s
conftest.py. Imports inside functions are rewritten too. The changed files then get `ruff check --select I --fix`
(import order) and `ruff format`. Running it again changes nothing.

The library's moves, in any file given (tracer/, server/, bench/ too): `tracer.rendering.compile` and
`tracer.rendering.parallel` are `tracer.kernels.compile` and `tracer.kernels.parallel`; the integrators' table
(`INTEGRATORS`, `BY_NAME`, `NAMES`, `IntegratorInfo`) is `tracer.scene.integrators`'s; the film's filters
(`FILTER_TABLE`, `filter_1d`, `filter_tables`) are `tracer.kernels.filters`'."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TESTS = ROOT / "tests"
SUPPORT = TESTS / "support"

# old bare module -> the module that holds all of its names now
WHOLE = {
    "conftest": "tests.support.scene",  # the re-exports of scene_support (ROOT, SCENES, EXAMPLES, scene_dict, small)
    "scene_support": "tests.support.scene",
    "test_api_support": "tests.support.api",
    "queue_support": "tests.support.queue",
    "hosts": "tests.support.hosts",
    "lti_platform": "tests.support.lti_platform",
    "layering": "tests.support.layering",
    "zoo_tracer": "tests.owntracer.zoo_tracer",
    "zoo_trees": "tests.owntracer.zoo_trees",
}
# a test module whose shared helpers moved to a support module (the names the support module defines go there)
HELPERS = {
    "test_assets": "tests.support.assets",
    "test_dashboard": "tests.support.dashboard",
    "test_disk_full": "tests.support.disk",
    "test_grading": "tests.support.grading",
    "test_grading_upload": "tests.support.grading_upload",
    "test_lms": "tests.support.lms",
    "test_migrations": "tests.support.migrations",
    "test_own_trees": "tests.support.own_trees",
    "test_samples": "tests.support.samples",
    "test_store": "tests.support.store",
    "test_api_assignments": "tests.support.assignments",
    "test_api_assignments_restart": "tests.support.assignments_restart",
    "test_web_axe": "tests.support.axe",
    "test_web_course_instructor": "tests.support.course_page",
    "test_web_grading": "tests.support.grading_page",
    "test_web_page": "tests.support.page",
}
GONE = {"lti_support": {"platform", "tool"}}  # fixtures now registered by tests/server/lti/conftest.py
# the library's modules that moved (tracer/ layered by package), and names that moved out of a module that stayed
TRACER_MODULES = {
    "tracer.rendering.compile": "tracer.kernels.compile",
    "tracer.rendering.parallel": "tracer.kernels.parallel",
}
TRACER_NAMES = {
    "tracer.integrators": dict.fromkeys(
        ("INTEGRATORS", "BY_NAME", "NAMES", "IntegratorInfo"), "tracer.scene.integrators"
    ),
    "tracer.rendering.film": dict.fromkeys(("FILTER_TABLE", "filter_1d", "filter_tables"), "tracer.kernels.filters"),
}


def _top_names(module: str) -> set[str]:
    path = ROOT / (module.replace(".", "/") + ".py")
    names: set[str] = set()
    for st in ast.parse(path.read_text()).body:
        if isinstance(st, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(st.name)
        elif isinstance(st, ast.Assign):
            names.update(n.id for t in st.targets for n in ast.walk(t) if isinstance(n, ast.Name))
        elif isinstance(st, ast.AnnAssign) and isinstance(st.target, ast.Name):
            names.add(st.target.id)
        elif isinstance(st, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in st.names)
    return names


def _test_modules() -> dict[str, str]:
    """Every module of tests/ by its bare name -> its dotted name."""
    found = {}
    for path in sorted(TESTS.rglob("*.py")):
        if "__pycache__" in path.parts or path.name in ("__init__.py", "conftest.py") or SUPPORT in path.parents:
            continue
        found.setdefault(path.stem, ".".join(path.relative_to(ROOT).with_suffix("").parts))
    return found


def _alias(a: ast.alias) -> str:
    return a.name if a.asname is None else f"{a.name} as {a.asname}"


def convert(path: Path, modules: dict[str, str], warn) -> bool:
    text = path.read_text()
    try:
        tree = ast.parse(text)
    except SyntaxError as exc:
        warn(f"{path}: not parsed ({exc})")
        return False
    lines = text.splitlines(keepends=True)
    edits = []  # (first line, last line, new text), 1-based, inclusive
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            old = node.module
            if old in WHOLE:
                groups = {WHOLE[old]: list(node.names)}
            elif old in TRACER_MODULES:
                groups = {TRACER_MODULES[old]: list(node.names)}
            elif old in TRACER_NAMES:
                if not any(a.name in TRACER_NAMES[old] for a in node.names):
                    continue
                groups = {}
                for a in node.names:
                    groups.setdefault(TRACER_NAMES[old].get(a.name, old), []).append(a)
            elif old in GONE:
                left = [a for a in node.names if a.name not in GONE[old]]
                if left:
                    warn(f"{path}:{node.lineno}: {old} is gone; {[a.name for a in left]} not rewritten")
                    continue
                groups = {}
            elif old in HELPERS or old in modules:
                groups = {}
                support = HELPERS.get(old)
                held = _top_names(support) if support else set()
                for a in node.names:
                    if a.name in held:
                        groups.setdefault(support, []).append(a)
                    else:
                        where = modules.get(old)
                        if where is None:
                            warn(f"{path}:{node.lineno}: {a.name} of {old} not found")
                            continue
                        warn(
                            f"{path}:{node.lineno}: {a.name} imported from the test module {where}: move it to support"
                        )
                        groups.setdefault(where, []).append(a)
            else:
                continue
            indent = " " * node.col_offset
            tail = lines[node.end_lineno - 1][node.end_col_offset :]
            comment = tail[tail.index("#") :].rstrip("\n") if "#" in tail else ""
            new = [f"{indent}from {mod} import {', '.join(_alias(a) for a in names)}" for mod, names in groups.items()]
            if comment and new:
                new[0] += "  " + comment
            if not new:
                new = [f"{indent}pass"] if node.col_offset else []
            edits.append((node.lineno, node.end_lineno, "".join(n + "\n" for n in new)))
        elif isinstance(node, ast.Import):
            moved = [a for a in node.names if a.name in TRACER_MODULES]
            if len(node.names) == 1 and moved and moved[0].asname:
                a = moved[0]
                line = f"{' ' * node.col_offset}import {TRACER_MODULES[a.name]} as {a.asname}\n"
                edits.append((node.lineno, node.end_lineno, line))
                continue
            for a in moved:
                warn(f"{path}:{node.lineno}: `import {a.name}`: it is {TRACER_MODULES[a.name]} now (by hand)")
            for a in node.names:
                if a.name in WHOLE or a.name in HELPERS or a.name in modules:
                    warn(f"{path}:{node.lineno}: `import {a.name}`: use its names from tests.support (by hand)")
    if not edits:
        return False
    for first, last, new in sorted(edits, reverse=True):
        lines[first - 1 : last] = [new]
    path.write_text("".join(lines))
    return True


def main(argv: list[str]) -> int:
    targets = [Path(a) for a in argv] or [TESTS]
    files = sorted(
        {p for t in targets for p in ([t] if t.is_file() else t.rglob("*.py")) if "__pycache__" not in p.parts}
    )
    files = [f for f in files if f.resolve() != Path(__file__).resolve()]
    modules = _test_modules()
    warnings: list[str] = []
    changed = [f for f in files if convert(f, modules, warnings.append)]
    for w in warnings:
        print("warning:", w, file=sys.stderr)
    if changed:
        ruff = [sys.executable, "-m", "ruff"]
        subprocess.run([*ruff, "check", "--select", "I", "--fix", "-q", *map(str, changed)], cwd=ROOT, check=False)
        subprocess.run([*ruff, "format", "-q", *map(str, changed)], cwd=ROOT, check=False)
    print(f"{len(changed)} file(s) rewritten")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
