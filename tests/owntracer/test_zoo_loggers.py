"""The tree loggers students copy (docs/own-tracer/treelog.py and treelog.hpp) write tree logs the service
takes: tracer.grading.treelog.validate finds nothing wrong in them."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest

from tests.owntracer.zoo_tracer import tree_log, treelog, zoo_scene
from tests.support.scene import ROOT
from tracer.grading.treelog import validate

GXX = Path("/usr/bin/g++")
HEADER = ROOT / "docs" / "own-tracer" / "treelog.hpp"

# A two-node tree: the eye ray hits the floor (object 0), and its shadow ray reaches light 0.
EYE_ORIGIN, EYE_DIR = [0.0, 1.0, 5.0], [0.0, -0.6, -0.8]
HIT_T, HIT_POINT, NORMAL = 1.6666666666666667, [0.0, 0.0, 3.6666666666666665], [0.0, 1.0, 0.0]
SHADOW_DIR, CARRIED = [0.0, 1.0, 0.0], [0.25, 0.5, 0.125]

CPP_PROGRAM = """
#include "treelog.hpp"
#include <iostream>

struct V { double x, y, z; };  // a student's own vector type

int main() {
    treelog::TreeLog log;
    treelog::PixelTree& tree = log.pixel(3, 4);
    int eye = tree.eye({0.0, 1.0, 5.0}, treelog::xyz(V{0.0, -0.6, -0.8}));
    tree.hit(eye, 1.6666666666666667, {0.0, 0.0, 3.6666666666666665}, {0.0, 1.0, 0.0}, 0);
    double up[3] = {0.0, 1.0, 0.0};
    tree.shadow(eye, {0.0, 1e-4, 3.6666666666666665}, treelog::vec(up), 0, false, {0.25, 0.5, 0.125}, {1, 1, 1});
    tree.radiance(eye, {0.3, 0.55, 0.175});
    tree.terms(eye, {0.05, 0.05, 0.05}, {0.25, 0.5, 0.125}, {0, 0, 0});
    tree.color({0.3, 0.55, 0.175});
    log.pixel(5, 6).eye({0, 1, 5}, {0, 0, -1});  // a second pixel: a miss
    std::cout << log.json();
    return 0;
}
"""


def python_two_node_log() -> dict:
    log = treelog.TreeLog()
    tree = log.pixel(3, 4)
    eye = tree.eye(EYE_ORIGIN, EYE_DIR)
    tree.hit(eye, HIT_T, HIT_POINT, NORMAL, 0)
    tree.shadow(eye, [0.0, 1e-4, HIT_POINT[2]], SHADOW_DIR, 0, False, radiance=CARRIED, weight=[1, 1, 1])
    tree.set(eye, radiance=[0.3, 0.55, 0.175], terms={"ambient": 0.05, "diffuse": CARRIED, "specular": 0})
    tree.color = [0.3, 0.55, 0.175]
    miss = log.pixel(5, 6)
    miss.miss(miss.eye([0, 1, 5], [0, 0, -1]))
    return json.loads(log.dumps())


def check_two_node_log(obj: dict) -> None:
    """The two trees as logged, and valid."""
    assert validate(obj) == []
    first, second = obj["trees"]
    assert first["pixel"] == [3, 4]
    assert second["pixel"] == [5, 6]
    eye, shadow = first["nodes"]
    assert (eye["id"], eye["parent"], eye["kind"]) == (0, None, "eye")
    assert (shadow["id"], shadow["parent"], shadow["kind"]) == (1, 0, "shadow")
    assert eye["direction"] == EYE_DIR
    assert eye["t"] == HIT_T
    assert eye["hit"] == {"point": HIT_POINT, "normal": NORMAL, "object": 0}
    assert (shadow["light"], shadow["occluded"], shadow["t"], shadow["hit"]) == (0, False, None, None)
    assert shadow["radiance"] == CARRIED
    assert shadow["weight"] == [1, 1, 1]
    assert eye["terms"]["diffuse"] == CARRIED
    assert eye["terms"]["ambient"] == [0.05] * 3
    assert first["color"] == [0.3, 0.55, 0.175]
    (miss,) = second["nodes"]
    assert miss["t"] is None
    assert miss["hit"] is None


def test_zoo_loggers_python_writes_a_valid_log(tmp_path):
    check_two_node_log(python_two_node_log())
    log = treelog.TreeLog()
    log.pixel(0, 0).eye([0, 0, 0], [0, 0, -1])
    log.write(tmp_path / "treelog.json")
    assert validate(json.loads((tmp_path / "treelog.json").read_text())) == []


def test_zoo_loggers_python_log_of_the_zoo_tracer_is_valid():
    """The student tracer's own log: deep trees with every kind of ray."""
    obj = tree_log(zoo_scene(), [(0, 0), (13, 23), (30, 25), (18, 27), (38, 18)])
    assert validate(obj) == []
    kinds = {n["kind"] for tree in obj["trees"] for n in tree["nodes"]}
    assert kinds == {"eye", "shadow", "reflection", "transmission"}
    assert json.loads(json.dumps(obj, allow_nan=False)) == obj


def test_zoo_loggers_python_writes_null_for_a_number_that_is_not_finite():
    log = treelog.TreeLog()
    tree = log.pixel(1, 2)
    tree.hit(tree.eye([0, 0, 0], [0, 0, -1]), math.nan, [0, 0, math.inf], [0, 0, 1], 2)
    obj = json.loads(log.dumps())  # still JSON
    node = obj["trees"][0]["nodes"][0]
    assert node["t"] is None
    assert node["hit"]["point"] == [0, 0, None]
    assert validate(obj) != [], "the service's check names the field that is not a number"


def test_zoo_loggers_python_refuses_what_no_tree_has():
    tree = treelog.TreeLog().pixel(0, 0)
    with pytest.raises(ValueError, match="kind"):
        tree.add("refraction", None, [0, 0, 0], [0, 0, 1])
    with pytest.raises(ValueError, match="parent"):
        tree.reflection(3, [0, 0, 0], [0, 0, 1])
    with pytest.raises(ValueError, match="no field"):
        tree.set(tree.eye([0, 0, 0], [0, 0, 1]), colour=[1, 1, 1])
    log = treelog.TreeLog()
    for i in range(treelog.TreeLog.MAX_TREES):
        log.pixel(i, 0)
    with pytest.raises(ValueError, match="at most 64"):
        log.pixel(0, 1)


def test_zoo_loggers_cpp_writes_a_valid_log(tmp_path):
    assert GXX.exists(), f"the C++ logger's test compiles with g++, which is not at {GXX} (apt-get install g++)"
    source = tmp_path / "two_nodes.cpp"
    source.write_text(CPP_PROGRAM)
    program = tmp_path / "two_nodes"
    flags = ["-std=c++17", "-Wall", "-Wextra", "-Wpedantic", "-Werror", f"-I{HEADER.parent}"]
    built = subprocess.run(
        [str(GXX), *flags, str(source), "-o", str(program)], capture_output=True, text=True, timeout=120
    )
    assert built.returncode == 0, built.stderr
    ran = subprocess.run([str(program)], capture_output=True, text=True, timeout=30)
    assert ran.returncode == 0, ran.stderr
    obj = json.loads(ran.stdout)
    check_two_node_log(obj)
    # the C++ logger writes every field (null when not set); the Python one leaves unset fields out
    assert obj["trees"][1]["nodes"][0]["radiance"] is None
