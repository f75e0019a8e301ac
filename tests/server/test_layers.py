"""The service's shape (server/): packages in layers, each importing only those below it, no import cycle
anywhere (type-only imports counted), HTTP spoken by server/api alone, and the routes' dependencies in one place
(the tracer's own shape is checked in test_structs.py)."""

from __future__ import annotations

import ast
import subprocess
import sys

from tests.support.layering import LazyGraph, cycles, imports_of, modules
from tests.support.scene import ROOT

SERVER = LazyGraph("server")  # every import, those made only for type checkers too
AT_RUN_TIME = LazyGraph("server", typing=False)
# imports across the layers that type checkers alone see: the job service names the queue's interface (whose
# backends import jobs) for them, and calls the queue handed to it
TYPE_ONLY = {("server.jobs.service", "server.queue.base")}
TOP = {"server", "server.main", "server.__main__", "server.worker"}  # the app's wiring and the entry points: anything
HTTP = ("fastapi", "starlette", "fastapi_offline")  # the web framework: server/api's, and the app's (server/main.py)
SPEAK_HTTP = ("server.api", "server.main")
LAYERS = {  # a package of server/ -> what of server/ its modules may import (a prefix: the package or a module)
    "server.core": set(),  # settings, errors, security, start-up checks, the disk and SQLite helpers
    "server.jobs": {"server.core"},  # life cycle, store, files, the job service, janitor, previews
    "server.checkers": {"server.core"},  # the scene checking processes
    "server.queue": {"server.core", "server.jobs"},  # the interface, the render try, embedded/ and redis/
    "server.grading": {"server.core", "server.jobs"},  # grading runs, their store, uploads
    "server.lti": {"server.core"},  # LTI 1.3: the tool's keys, platforms, launch checks, the Advantage services
    # courses, their people, assignments, rosters, submissions, grades; what an LTI launch opens
    "server.course": {"server.core", "server.jobs", "server.grading", "server.lti"},
    # the routes: the job service and its store, and the queue's interface only (never a backend)
    "server.api": {
        "server.core",
        "server.jobs",
        "server.checkers",
        "server.grading",
        "server.course",
        "server.lti",
        "server.queue.base",
    },
}


def layer(module: str) -> str | None:
    return next((p for p in LAYERS if module == p or module.startswith(p + ".")), None)


def allowed(module: str, imported: str) -> bool:
    own = layer(module)
    if own is None or layer(imported) == own:
        return True
    return any(imported == p or imported.startswith(p + ".") for p in LAYERS[own])


def test_layers_every_module_is_in_a_layer_or_at_the_top():
    assert [m for m in SERVER if layer(m) is None and m not in TOP] == []


def test_layers_each_package_imports_only_the_layers_below_it():
    offenders = {
        m: sorted(i for i in deps if not allowed(m, i) and (m, i) not in TYPE_ONLY) for m, deps in SERVER.items()
    }
    assert {m: i for m, i in offenders.items() if i} == {}


def test_layers_the_exceptions_are_type_only_imports():
    for module, imported in TYPE_ONLY:
        assert imported in SERVER[module] and imported not in AT_RUN_TIME[module], (module, imported)


def test_layers_the_rule_catches_a_route_that_reaches_into_a_backend():
    assert not allowed("server.api.routes.jobs", "server.queue.redis.queue")
    assert not allowed("server.queue.embedded.worker", "server.api.models")
    assert not allowed("server.jobs.service", "server.queue.base")  # the service only calls the interface
    assert allowed("server.api.deps", "server.queue.base")
    assert not allowed("server.lti.launch", "server.course.service")  # the course wires the handler, not lti
    assert allowed("server.api.routes.lti", "server.lti.launch")


def test_layers_the_service_has_no_import_cycle():
    assert cycles(SERVER) == []


def test_layers_type_only_imports_count_for_cycles():
    """An import under `if TYPE_CHECKING:` is an edge of the graph the cycle check reads: the grading run named its
    runs so (run.py <-> runs.py) and the check did not see it; it would now."""
    known = modules("server")
    assert "server.queue.base" in imports_of("server.jobs.service", known)
    assert "server.queue.base" not in imports_of("server.jobs.service", known, typing=False)
    assert cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]


def test_layers_a_grading_run_does_not_know_its_runs():
    """A run reports back through its RunContext (server/grading/run_base.py); the runs start it. Nor do its parts
    (run_base.py, run_renders.py, run_tasks.py) know the runs."""
    assert "server.grading.run" in SERVER["server.grading.runs"]
    for part in ("run", "run_base", "run_renders", "run_tasks"):
        assert "server.grading.runs" not in SERVER[f"server.grading.{part}"], part


# -- HTTP is server/api's ----------------------------------------------------------------------------------------


def http_imports(module: str) -> list[str]:
    """The web framework's modules that `module` imports (type-only imports too)."""
    return sorted(i for i in imports_of(module, modules("server")) if i.split(".")[0] in HTTP)


def test_layers_only_the_api_speaks_http():
    """Nothing outside server/api (and server/main.py, which assembles the app) imports FastAPI or Starlette: the
    services raise domain errors (server/core/errors.py) and return plain answers (server/core/answers.py), and
    server/api makes the responses."""
    outside = {m: http_imports(m) for m in SERVER if not any(m == p or m.startswith(p + ".") for p in SPEAK_HTTP)}
    assert {m: i for m, i in outside.items() if i} == {}


def test_layers_the_http_rule_sees_the_api():
    assert http_imports("server.api.errors") and http_imports("server.main")
    assert "starlette.types" in http_imports("server.api.middleware")


def _route_modules() -> dict[str, ast.Module]:
    return {
        m: ast.parse(p.read_text(), str(p)) for m, p in modules("server").items() if m.startswith("server.api.routes.")
    }


def test_layers_the_routes_take_their_dependencies_from_deps():
    """Who calls, the role checks, the stores and services: server/api/deps.py's aliases, not made again per route
    module, and no route reaches into the app's state on its own."""
    aliases, state = [], []
    for m, tree in _route_modules().items():
        for node in tree.body:  # X = Annotated[..., Depends(...)] at the top of a route module
            value = node.value if isinstance(node, ast.Assign) else None
            if (
                isinstance(value, ast.Subscript)
                and ast.unparse(value.value) == "Annotated"
                and "Depends(" in ast.unparse(value)
            ):
                aliases.append(f"{m}: {ast.unparse(node)}")
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr == "state" and ast.unparse(node.value).endswith("app"):
                state.append(f"{m}:{node.lineno}")
    assert aliases == []
    assert state == []


def test_layers_every_service_module_imports_in_a_fresh_interpreter():
    code = "import importlib, sys\nfor name in sys.argv[1:]:\n    importlib.import_module(name)\n"
    names = [m for m in modules("server") if m != "server.__main__"]
    p = subprocess.run([sys.executable, "-c", code, *names], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
