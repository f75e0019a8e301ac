"""Lights (tracer/kernels/lights.py): kinds from the scene format's light types, their LightData, the area lights'
own shapes. Their sampling and radiometry are tested in test_distribution.py (chi-square of the sampled
points, irradiance against Lambert's formula) and test_analytic.py."""

import math

import numpy as np
import pytest

from tracer.grading.spec import PRESETS
from tracer.kernels.compile import compile_scene
from tracer.kernels.kinds import Shape
from tracer.kernels.lights import LightKind, light_data, light_shape
from tracer.scene import AREA_LIGHT_TYPES, LIGHT_TYPES, load_scene

LIGHTS = {
    "point": {"type": "point", "position": [0, 2, 0], "intensity": 3},
    "directional": {"type": "directional", "direction": [0, -2, 0], "irradiance": 2},
    "spot": {"type": "spot", "position": [0, 2, 0], "direction": [0, -1, 0], "cutoff": 60, "falloff": 2},
    "quad": {"type": "quad", "corner": [-1, 2, -1], "edge1": [2, 0, 0], "edge2": [0, 0, 2], "radiance": 4},
    "disk": {"type": "disk", "center": [0, 2, 0], "normal": [0, -3, 0], "radius": 0.5, "radiance": 4},
    "sphere": {"type": "sphere", "center": [0, 2, 0], "radius": 0.25, "radiance": 4},
}


def scene_with(*lights):
    return load_scene({"camera": {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0]}, "lights": list(lights)})[0]


def test_lights_kinds_follow_the_scene_format():
    assert [k.name.lower() for k in LightKind] == list(LIGHT_TYPES) == list(LIGHTS)
    assert AREA_LIGHT_TYPES == ["quad", "disk", "sphere"]
    assert PRESETS["area_light"]["where"]["type"]["one_of"] == AREA_LIGHT_TYPES


@pytest.mark.parametrize("kind", list(LIGHTS))
def test_lights_data_of_each_type(kind):
    d = light_data(scene_with(LIGHTS[kind]).lights[0])
    assert d.kind == LightKind[kind.upper()]
    assert d.shape == -1  # compile_scene sets an area light's shape
    if kind in ("directional", "spot", "disk"):  # unit directions, whatever length the scene gave
        assert np.linalg.norm(np.array(d.direction)) == pytest.approx(1.0, abs=1e-6)
    area = {"quad": 4.0, "disk": math.pi * 0.25, "sphere": 4 * math.pi * 0.0625}
    assert d.area == pytest.approx(area.get(kind, 0.0), rel=1e-6)
    if kind == "spot":
        assert d.cos_cutoff == pytest.approx(0.5, abs=1e-6)


def test_lights_area_lights_are_shapes_rays_can_see():
    scene = scene_with(*LIGHTS.values())
    cs = compile_scene(scene)
    shapes, lights = cs.data.shapes.numpy(), cs.data.lights.numpy()
    assert cs.num_shapes == 3
    for k, light in enumerate(scene.lights):
        if light.type in AREA_LIGHT_TYPES:
            kind, _ = light_shape(light)
            s = shapes[lights[k]["shape"]]
            assert (s["kind"], s["light"], s["obj"]) == (kind, k, -1 - k)
            assert cs.material_names[s["mat"]] == f"lights[{k}]"
        else:
            assert lights[k]["shape"] == -1
            with pytest.raises(ValueError):
                light_shape(light)
    assert [shapes[i]["kind"] for i in range(3)] == [Shape.QUAD, Shape.DISK, Shape.SPHERE]
