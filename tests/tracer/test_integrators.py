"""The integrators' one table (tracer/scene/integrators.py) and their one interface.

What each integrator computes is tested by the scenes: test_analytic.py, test_distribution.py
(path against whitted, MIS), test_radiosity.py, test_render.py (every example, ray trees)."""

import importlib
import re
from typing import get_args

import pytest

from tests.support.scene import ROOT
from tracer.errors import SceneError
from tracer.grading.spec import RenderOverrides
from tracer.integrators import dispatch
from tracer.kernels.kinds import Integrator
from tracer.scene import RenderSettings, load_scene, scene_json_schema
from tracer.scene.integrators import INTEGRATORS, NAMES


def test_integrators_one_table_names_them_everywhere():
    assert NAMES == ("whitted", "path", "radiosity")
    assert [(m.name.lower(), m.value) for m in Integrator] == [(n, k) for k, n in enumerate(NAMES)]
    assert get_args(RenderSettings.model_fields["integrator"].annotation) == NAMES
    assert get_args(get_args(RenderOverrides.model_fields["integrator"].annotation)[0]) == NAMES
    assert set(dispatch.KERNELS) == set(Integrator)
    assert set(dispatch.KERNEL_MODULES) == {i.kernels for i in INTEGRATORS}


def test_integrators_are_published_in_the_json_schema():
    field = scene_json_schema()["$defs"]["RenderSettings"]["properties"]["integrator"]
    assert field["enum"] == list(NAMES)
    assert [e["name"] for e in field["x-integrators"]] == list(NAMES)
    assert all(e["description"].endswith(".") and "\n" not in e["description"] for e in field["x-integrators"])


def test_integrators_the_table_says_what_is_solved_first_and_what_a_sample_costs():
    assert {i.name: (i.prepass, i.cost) for i in INTEGRATORS} == {
        "whitted": (None, "tree"),
        "path": (None, "path"),
        "radiosity": ("radiosity", "tree"),
    }
    scene, _ = load_scene({"camera": {"lookfrom": [0, 0, 1], "lookat": [0, 0, 0]}, "render": {"integrator": "path"}})
    assert scene.render.integrator_info is INTEGRATORS[NAMES.index("path")]


def test_integrators_are_named_only_by_their_table():
    """Code outside the table asks an integrator's row (its prepass, its cost), never compares its name."""
    members = "|".join(n.upper() for n in NAMES)
    pattern = re.compile(rf"\.integrator\s*(==|!=|in |not in )|Integrator\.({members})\b")
    found = [
        f"{path.relative_to(ROOT)}:{k}: {line.strip()}"
        for folder in ("tracer", "server")
        for path in sorted((ROOT / folder).rglob("*.py"))
        if path != ROOT / "tracer" / "integrators" / "__init__.py"
        for k, line in enumerate(path.read_text().splitlines(), 1)
        if pattern.search(line)
    ]
    assert found == []


def test_integrators_share_their_kernels_where_the_table_says():
    """radiosity is the ray tree with a solution: the same compiled kernels as whitted."""
    assert dispatch.KERNELS[Integrator.RADIOSITY] is dispatch.KERNELS[Integrator.WHITTED]
    assert dispatch.KERNELS[Integrator.PATH] is not dispatch.KERNELS[Integrator.WHITTED]


def test_integrators_trace_with_one_signature():
    """Every integrator's `trace`, and whitted_simple's (Whitted in lecture size, in no table), which
    dispatch.make_kernels makes kernels of the same way."""
    modules = (*dispatch.KERNEL_MODULES, "whitted_simple")
    traces = {m: importlib.import_module(f"tracer.integrators.{m}").trace for m in modules}
    signatures = {
        m: [(k, getattr(t, "__name__", repr(t))) for k, t in f.input_types.items()] for m, f in traces.items()
    }
    first = next(iter(signatures.values()))
    assert [k for k, _ in first] == ["scene", "o", "d", "time", "rng", "key", "sample", "st", "row", "record", "rec"]
    assert all(s == first for s in signatures.values()), signatures


def test_integrators_an_unknown_name_lists_the_table():
    with pytest.raises(SceneError) as e:
        load_scene({"camera": {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0]}, "render": {"integrator": "pathh"}})
    [err] = e.value.errors
    assert err["path"] == "render.integrator"
    assert err["message"] == "expected one of: whitted, path, radiosity; got \"pathh\"; did you mean 'path'?"
