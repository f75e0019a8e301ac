"""The service's shape (server/): packages in layers, each importing only those below it, and no import
cycle anywhere (the tracer's own shape is checked in test_structs.py)."""

from __future__ import annotations

import subprocess
import sys

from conftest import ROOT
from layering import cycles, graph, modules

SERVER = graph("server")
TOP = {"server", "server.main", "server.__main__", "server.worker"}  # the app's wiring and the entry points: anything
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
    "server.api": {"server.core", "server.jobs", "server.checkers", "server.grading", "server.course",
                   "server.lti", "server.queue.base"},
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
    offenders = {m: sorted(i for i in deps if not allowed(m, i)) for m, deps in SERVER.items()}
    assert {m: i for m, i in offenders.items() if i} == {}


def test_layers_the_rule_catches_a_route_that_reaches_into_a_backend():
    assert not allowed("server.api.routes.jobs", "server.queue.redis.queue")
    assert not allowed("server.queue.embedded.worker", "server.api.models")
    assert not allowed("server.jobs.service", "server.queue.base")  # the service only calls the interface
    assert allowed("server.api.deps", "server.queue.base")
    assert not allowed("server.lti.launch", "server.course.service")  # the course wires the handler, not lti
    assert allowed("server.api.routes.lti", "server.lti.launch")


def test_layers_the_service_has_no_import_cycle():
    assert cycles(SERVER) == []


def test_layers_every_service_module_imports_in_a_fresh_interpreter():
    code = "import importlib, sys\nfor name in sys.argv[1:]:\n    importlib.import_module(name)\n"
    names = [m for m in modules("server") if m != "server.__main__"]
    p = subprocess.run([sys.executable, "-c", code, *names], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
