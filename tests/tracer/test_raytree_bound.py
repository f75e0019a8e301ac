"""The bound on a pixel sample's ray tree (max_tree_rays, tracer/limits.py): the kernel keeps it, the image
and the ray tree alike, and the tree says where it cut (end max_tree_rays). The case of issue 24: a glass
ball in a box of mirrors, max_depth 64, min_weight 0, whose tree grows about 1.6 times a level."""

import json
import re

import numpy as np

from tests.support.scene import ROOT
from tracer.kernels.compile import compile_scene
from tracer.kernels.kinds import End
from tracer.limits import Limits
from tracer.rendering.progressive import render
from tracer.rendering.raytree import END_WORDS, ray_tree, tree_text
from tracer.scene import load_scene

MIRROR_BOX = ROOT / "tests" / "tracer" / "mirror_box.json"


def mirror_box(max_depth: int = 64, **film) -> dict:
    data = json.loads(MIRROR_BOX.read_text())
    data["render"]["max_depth"] = max_depth
    data["film"].update(film)
    return data


def tree_rays(tree: dict) -> int:
    return sum(1 for n in tree["nodes"] if n["kind"] != "shadow")


def test_raytree_bound_cuts_the_mirror_box_tree_and_says_so(compiled_kernels):
    """Before the bound this tree never ended (one launch ran until the worker was killed)."""
    scene, _ = load_scene(mirror_box())
    cs = compile_scene(scene)
    tree = ray_tree(cs, 0, 0)
    assert tree["max_tree_rays"] == Limits().max_tree_rays == 1024
    assert tree_rays(tree) == 1024 and not tree["truncated"]
    cut = [n for n in tree["nodes"] if n["end"] == "max_tree_rays"]
    assert cut
    assert all(n["kind"] != "shadow" and n["hit"] for n in cut)
    assert all(n["depth"] < 64 for n in cut)  # cut by the bound, long before max_depth
    # the image's sample obeys the same bound: the same rays, the same colour
    r = render(cs, threads=1)
    assert r.rays["eye"] + r.rays["reflection"] + r.rays["transmission"] == 1024
    assert r.rays["shadow"] == sum(1 for n in tree["nodes"] if n["kind"] == "shadow")
    np.testing.assert_allclose(tree["color"], r.image[0, 0], rtol=1e-5, atol=1e-7)  # float32 sums of 1024 rays
    text = tree_text(tree)
    assert "ended: max tree rays: a reflection or transmission ray was wanted" in text
    assert "(cut: the sample's tree reached its bound of 1024 rays, max_tree_rays)" in text


def test_raytree_bound_is_the_service_s_limit():
    scene, _ = load_scene(mirror_box())
    tree = ray_tree(compile_scene(scene, limits=Limits(max_tree_rays=64)), 0, 0)
    assert tree["max_tree_rays"] == 64 and tree_rays(tree) == 64
    assert any(n["end"] == "max_tree_rays" for n in tree["nodes"])


def test_raytree_bound_leaves_a_smaller_tree_as_it_was():
    """At max_depth 10 the tree has 231 eye, reflection and transmission rays (the issue's 407 rays with the
    shadow rays): a bound of 231 changes nothing, node for node; 230 cuts the last wanted ray."""
    scene, _ = load_scene(mirror_box(10))
    free = ray_tree(compile_scene(scene, limits=Limits(max_tree_rays=1_000_000)), 0, 0)
    assert tree_rays(free) == 231 and len(free["nodes"]) == 407
    exact = ray_tree(compile_scene(scene, limits=Limits(max_tree_rays=231)), 0, 0)
    assert {k: v for k, v in exact.items() if k != "max_tree_rays"} == {
        k: v for k, v in free.items() if k != "max_tree_rays"
    }
    assert not any(n["end"] == "max_tree_rays" for n in exact["nodes"])
    less = ray_tree(compile_scene(scene, limits=Limits(max_tree_rays=230)), 0, 0)
    assert tree_rays(less) == 230
    assert [n["id"] for n in less["nodes"] if n["end"] == "max_tree_rays"] != []


def test_raytree_bound_words_are_the_page_s():
    """Every end reason has its words, the same in `raytree --text` and on the page (web/js/rays.js)."""
    js = (ROOT / "web" / "js" / "rays.js").read_text()
    block = re.search(r"export const END_WORDS = \{\n(.*?)\n\};", js, re.S)[1]
    page = dict(re.findall(r'^\s+(\w+):\s+"(.*)",$', block, re.M))  # a long one on the key's next line (biome)
    assert page == END_WORDS
    assert set(END_WORDS) == {e.name.lower() for e in End if e != End.NONE}
