"""Writes the example class of submissions (the fixtures of tests/tracer/grading/test_grading.py) (run from
the repository root: `python scenes/grading/make_class.py`). Each student is one case the tests grade exactly:

alice.json   the reference scene as is (correct)
bob.json     a point light instead of the area light (misses a requirement; hard shadows)
carol.json   not JSON (a trailing comma)
dave.json    correct, but 1 sample per pixel and 1 shadow ray (noisy)
erin.json    meets every requirement, but the picture is wrong (the mirror cube is grey, the red ball blue)
frank/       scene.json with schema errors (a typo'd field, an unknown material)
grace.png    a student's own render of the reference at 16 spp (our renderer, another seed): correct
heidi.exr    a student's own render without shadows and reflections (max_depth 1, no area light): wrong
ivan.png     an image of the wrong size
"""

import copy
import json
from pathlib import Path

import numpy as np

from tracer.kernels.compile import compile_scene
from tracer.rendering.film import write_exr, write_png
from tracer.rendering.progressive import render
from tracer.scene import load_scene

HERE = Path(__file__).resolve().parent
CLASS = HERE / "class"
REFERENCE = json.loads((HERE / "reference.json").read_text())


def save(name: str, scene: dict) -> None:
    (CLASS / name).parent.mkdir(parents=True, exist_ok=True)
    (CLASS / name).write_text(json.dumps(scene, indent=1) + "\n")


def image(scene: dict) -> np.ndarray:
    s, _ = load_scene(scene)
    return render(compile_scene(s), threads=1).image


def main() -> None:
    alice = copy.deepcopy(REFERENCE)
    alice["name"] = "Alice's glass ball"
    save("alice.json", alice)

    bob = copy.deepcopy(REFERENCE)
    bob["lights"] = [{"type": "point", "position": [0, 3.5, 0], "intensity": 20}]
    save("bob.json", bob)

    (CLASS / "carol.json").write_text('{"version": 1, "camera": {"lookfrom": [0, 1, 5], "lookat": [0, 0, 0],},}\n')

    dave = copy.deepcopy(REFERENCE)
    dave["sampler"] = {"type": "jittered", "spp": 1}
    dave["render"]["light_samples"] = 1
    save("dave.json", dave)

    erin = copy.deepcopy(REFERENCE)
    erin["materials"]["mirror"] = {"kd": 0.5}
    erin["materials"]["red"] = {"kd": [0.1, 0.2, 0.8]}
    save("erin.json", erin)

    frank = copy.deepcopy(REFERENCE)
    frank["objects"][1]["radus"] = frank["objects"][1].pop("radius")
    frank["objects"][3]["material"] = "rde"
    save("frank/scene.json", frank)

    grace = copy.deepcopy(REFERENCE)
    grace["render"]["seed"] = 4242
    write_png(CLASS / "grace.png", image(grace))

    heidi = copy.deepcopy(REFERENCE)
    heidi["render"]["max_depth"] = 1
    heidi["lights"] = [{"type": "point", "position": [0, 3.5, 0], "intensity": 0.0001}]
    heidi["ambient"] = 0.6
    write_exr(CLASS / "heidi.exr", image(heidi))

    ivan = copy.deepcopy(REFERENCE)
    ivan["film"] = {"width": 64, "height": 48}
    write_png(CLASS / "ivan.png", image(ivan))


if __name__ == "__main__":
    main()
