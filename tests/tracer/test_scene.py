"""Tests of tracer.scene: the scene format's models, validation errors and warnings, JSON Schema.

The corpus tests/bad_scenes/*.json holds one small invalid scene per kind of error;
tests/bad_scenes/expected.json lists, per file, the exact error paths and a substring of each message.
"""

import copy
import dataclasses
import io
import json
import math
import random
import re
from pathlib import Path

import pytest
from PIL import Image
from pydantic import ValidationError

from tests.support.assets import gltf_instanced, gltf_uri, no_repr, obj_grid, obj_uri, png_header_only, png_uri, uri
from tests.support.scene import ROOT
from tracer.scene import (
    ASSET_DIR,
    Box,
    DirectionalLight,
    Disk,
    DiskLight,
    ImageBump,
    ImageTexture,
    Limits,
    Material,
    Mesh,
    NoiseBump,
    Plane,
    PointLight,
    Quad,
    QuadLight,
    Scene,
    SceneError,
    Sphere,
    SphereLight,
    SpotLight,
    Triangle,
    load_scene,
    resolve_asset,
    scene_json_schema,
    validate_scene,
)

BAD_DIR = ROOT / "tests" / "bad_scenes"
SCENES_DIR = ROOT / "scenes"
EXPECTED = json.loads((BAD_DIR / "expected.json").read_text())

# SCENE_FORMAT.md's example with every documented field, plus one of each light and object type.
EXAMPLE = {
    "version": 1,
    "name": "Cornell box",
    "description": "An addition to SCENE_FORMAT.md: longer free text.",
    "camera": {
        "lookfrom": [0, 0, 3.9],
        "lookat": [0, 0, 0],
        "vup": [0, 1, 0],
        "vfov": 39.3,
        "lens_radius": 0.0,
        "focus_distance": None,
        "shutter": [0.0, 1.0],
    },
    "film": {"width": 256, "height": 256, "filter": {"type": "box"}, "exposure": 0.0},
    "sampler": {"type": "jittered", "spp": 16, "threshold": 0.05, "max_level": 3, "jitter": False},
    "render": {"integrator": "whitted", "max_depth": 5, "min_weight": 0.001, "light_samples": 1, "seed": 0},
    "background": [0.0, 0.0, 0.0],
    "ambient": [0.05, 0.05, 0.05],
    "fog": {"density": 0.0, "color": [0.5, 0.5, 0.5]},
    "materials": {
        "white": {"kd": 0.73},
        "glass": {"kd": 0, "kr": 1, "kt": 1, "ior": 1.5, "fresnel": True},
        "brushed": {"kd": 0.1, "ks": 0.6, "shininess": 200, "kr": 0.8, "gloss": 200},
        "floor": {
            "ka": 0.1,
            "emission": 0,
            "texture": {"type": "checker", "size": 1, "color1": 0.8, "color2": 0.2},
            "bump": {"type": "noise", "scale": 0.5, "strength": 0.2},
        },
        "poster": {
            "texture": {"type": "image", "file": "poster.png", "scale": [2, 1]},
            "bump": {"type": "image", "file": "textures/height.png", "strength": 0.5, "scale": [1, 1]},
        },
    },
    "lights": [
        {"type": "point", "position": [0, 1.9, 0], "intensity": 10, "attenuation": [0, 0, 1]},
        {"type": "directional", "direction": [0, -1, 0], "irradiance": [1, 1, 0.9]},
        {
            "type": "spot",
            "position": [0, 1.9, 0],
            "direction": [0, -1, 0],
            "intensity": 5,
            "cutoff": 30,
            "falloff": 4,
            "attenuation": [1, 0, 0],
        },
        {
            "type": "quad",
            "corner": [-0.2, 1.99, -0.2],
            "edge1": [0.4, 0, 0],
            "edge2": [0, 0, 0.4],
            "radiance": 15,
        },
        {"type": "disk", "center": [0, 1.99, 0], "normal": [0, -1, 0], "radius": 0.2, "radiance": 15},
        {"type": "sphere", "center": [0.5, 1.5, 0], "radius": 0.1, "radiance": [20, 18, 15]},
    ],
    "objects": [
        {
            "type": "sphere",
            "center": [0.4, -0.6, 0],
            "radius": 0.4,
            "material": "glass",
            "name": "glass ball",
        },
        {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "quad", "corner": [-1, -1, -1], "edge1": [2, 0, 0], "edge2": [0, 2, 0], "material": "white"},
        {"type": "disk", "center": [0, 0.99, 0], "normal": [0, -1, 0], "radius": 0.3, "material": "white"},
        {
            "type": "box",
            "min": [-0.3, -1, -0.3],
            "max": [0.3, 0.2, 0.3],
            "transform": {"translate": [-0.4, 0, 0], "rotate": [0, 20, 0], "scale": 1},
            "material": {"kd": [0.6, 0.2, 0.2]},
            "velocity": [0, 0.1, 0],
        },
        {"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "material": "brushed"},
        {
            "type": "mesh",
            "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
            "faces": [[0, 1, 2], [1, 3, 2]],
            "transform": {"scale": [1, 2, 1]},
            "smooth": True,
            "material": "poster",
        },
        {"type": "mesh", "file": "models/bunny.obj", "material": "white"},
    ],
}
MINIMAL = {"camera": {"lookfrom": [0, 0, 3], "lookat": [0, 0, 0]}}


def _scene(**changes) -> dict:
    data = copy.deepcopy(MINIMAL)
    data.update(copy.deepcopy(changes))
    return data


# ---------------------------------------------------------------------------------------------
# Errors: the corpus of bad scenes.


def test_bad_scenes_every_file_has_expectations():
    files = {p.name for p in BAD_DIR.glob("*.json")} - {"expected.json"}
    assert files == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bad_scenes_exact_paths_and_messages(name):
    with pytest.raises(SceneError) as info:
        load_scene(BAD_DIR / name)
    got = info.value.errors
    assert [e["path"] for e in got] == [e["path"] for e in EXPECTED[name]], got
    for want, error in zip(EXPECTED[name], got, strict=True):
        assert want["message"] in error["message"], error
    report = validate_scene((BAD_DIR / name).read_text())  # the same through JSON text
    assert not report["valid"]
    assert report["errors"] == got


def test_error_str_lists_one_error_per_line():
    with pytest.raises(SceneError) as info:
        load_scene(BAD_DIR / "several_errors.json")
    lines = str(info.value).splitlines()
    assert lines == [f"{e['path']}: {e['message']}" for e in info.value.errors]
    assert lines[0] == "film.width: must be >= 1"


def test_error_unknown_key_suggests_field_of_its_own_model():
    """'radus' on a box has no close field (a box has no radius): list what is allowed instead."""
    data = _scene(
        materials={"m": {}},
        objects=[{"type": "box", "material": "m", "min": [0, 0, 0], "max": [1, 1, 1], "radus": 1}],
    )
    (error,) = validate_scene(data)["errors"]
    assert error["path"] == "objects[0].radus"
    assert "did you mean" not in error["message"]
    assert "allowed: type, material, name" in error["message"]


SYNONYMS_SUGGESTED = [
    # (where the unknown field is, the field written, the field suggested)
    ("materials.m", "colour", "kd"),
    ("materials.m", "Color", "kd"),
    ("materials.m", "albedo", "kd"),
    ("materials.m", "diffuse", "kd"),
    ("materials.m", "specular", "ks"),
    ("materials.m", "exponent", "shininess"),
    ("materials.m", "mirror", "kr"),
    ("materials.m", "reflect", "kr"),
    ("materials.m", "transparency", "kt"),
    ("materials.m", "refraction", "kt"),
    ("materials.m", "eta", "ior"),
    ("materials.m", "index", "ior"),
    ("materials.m", "emissive", "emission"),
    ("lights[0]", "colour", "intensity"),
    ("lights[0]", "power", "intensity"),
    ("fog", "colour", "color"),
    ("camera", "fov", "vfov"),
    ("camera", "eye", "lookfrom"),
    ("camera", "up", "vup"),
    ("sampler", "samples", "spp"),
    ("render", "depth", "max_depth"),
]


@pytest.mark.parametrize(
    ("where", "word", "field"), SYNONYMS_SUGGESTED, ids=[f"{w}.{k}" for w, k, _ in SYNONYMS_SUGGESTED]
)
def test_error_unknown_key_suggests_the_field_other_renderers_name_so(where, word, field):
    """'colour' is not spelt like 'kd', but it is what a student means: a synonym is suggested, in the object
    that has that field (a material's colour is kd, a point light's its intensity, fog's its color)."""
    data = _scene(
        materials={"m": {}}, lights=[{"type": "point", "position": [0, 1, 0]}], fog={}, sampler={}, render={},
        objects=[{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
    )  # fmt: skip
    holder = data
    for key in where.replace("[0]", ".0").split("."):
        holder = holder[int(key)] if key.isdigit() else holder[key]
    holder[word] = 0.5
    (error,) = validate_scene(data)["errors"]
    assert error == {"path": f"{where}.{word}", "message": f"unknown field '{word}'; did you mean '{field}'?"}


def test_error_nan_and_infinity_from_python_values():
    data = _scene(fog={"density": math.inf}, ambient=[0, math.nan, 0])
    paths = [e["path"] for e in validate_scene(data)["errors"]]
    assert paths == ["ambient[1]", "fog.density"]


def test_error_inputs_that_are_not_scenes_never_raise():
    huge = '{"background": 1%s}' % ("0" * 5000)  # Python's json refuses integers of over 4300 digits
    deep = "[" * 100_000 + "]" * 100_000
    sources = [None, 5, "", "[1, 2]", b"\xff\xfe", b'{"camera": 1}', huge, deep, Path("/nonexistent.json")]
    for src in sources:
        report = validate_scene(src)
        assert report["valid"] is False and report["errors"], src
        assert all(set(e) == {"path", "message"} for e in report["errors"])


def test_error_numbers_too_large_for_a_float():
    data = _scene(background=10**400, camera={**MINIMAL["camera"], "vfov": 10**400})
    errors = {e["path"]: e["message"] for e in validate_scene(data)["errors"]}
    assert errors["background"].startswith("must be a finite number")
    assert "camera.vfov" in errors


def test_error_type_tag_that_is_not_a_string():
    data = _scene(objects=[{"type": None}, {"type": "Sphere"}])
    messages = [e["message"] for e in validate_scene(data)["errors"]]
    assert messages[0].startswith("unknown object type null; expected one of: sphere, plane")
    assert messages[1].endswith("did you mean 'sphere'?")


def test_error_cross_field_check_raised_by_the_model_itself():
    """Scene.model_validate without load_scene's context still checks names, at their own paths."""
    data = _scene(objects=[{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "nope"}])
    with pytest.raises(ValidationError) as info:
        Scene.model_validate(data)
    assert [e["loc"] for e in info.value.errors()] == [("objects", 0, "material")]


def _parse_path(path: str) -> list:
    tokens = re.findall(r'\.?([A-Za-z_][A-Za-z0-9_-]*)|\[(\d+)\]|\[("(?:[^"\\]|\\.)*")\]', path)
    return [name or (int(index) if index else json.loads(quoted)) for name, index, quoted in tokens]


def _exists(data, parts) -> bool:
    for part in parts:
        if isinstance(part, int) and isinstance(data, list) and part < len(data):
            data = data[part]
        elif isinstance(part, str) and isinstance(data, dict) and part in data:
            data = data[part]
        else:
            return False
    return True


def _mutations(data, rng, at=()):
    """Every (location, container) in a scene, to pick one to break."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for key, value in items:
        yield (*at, key), data
        yield from _mutations(value, rng, (*at, key))


# fmt: off
JUNK = [None, "x", -1, 0, 1e308, math.nan, True, [], {}, [1, 2], [0, 0, 0], {"type": "cone"}, "../../x",
        10**400]
# fmt: on


def test_error_paths_point_into_the_input_under_random_damage():
    """Fuzz: damaged scenes give only SceneError, and every error's parent path exists in the input
    (so no union tag such as 'sphere' leaks into a path, and no error lands on a made-up key)."""
    rng = random.Random(1)
    for _ in range(400):
        data = copy.deepcopy(EXAMPLE)
        for _ in range(rng.randint(1, 3)):
            location, container = rng.choice(list(_mutations(data, rng)))
            container[location[-1]] = copy.deepcopy(rng.choice(JUNK))
        report = validate_scene(data)
        for error in report["errors"]:
            parts = _parse_path(error["path"])
            assert error["path"] and _exists(data, parts[:-1]), error


# ---------------------------------------------------------------------------------------------
# Every independent error at once: checks between fields run beside the fields' own errors.

# (changes to the minimal scene, the errors expected: the last one is the check between fields)
INDEPENDENT = [
    (
        {"camera": {"lookfrom": [0, 0, 3], "lookat": [0, 0, 3], "vfov": 180}, "film": {"width": 0}},
        [
            ("camera.vfov", "must be < 180"),
            ("camera.lookat", "must differ from lookfrom (no view direction)"),
            ("film.width", "must be >= 1"),
        ],
    ),
    (
        {"render": {"max_depth": 65, "light_samples": 2000}},
        [
            ("render.max_depth", "must be <= 64"),
            ("render.light_samples", "must be at most 256 (limit max_light_samples)"),
        ],
    ),
    (
        {"sampler": {"type": "grid", "spp": 10, "max_level": 20}},
        [("sampler.max_level", "must be <= 8"), ("sampler.spp", "must be a perfect square for the grid sampler")],
    ),
    (
        {"sampler": {"type": "gird", "spp": 99999}},
        [("sampler.type", "expected one of: center, grid"), ("sampler.spp", "must be at most 4096 (limit max_spp)")],
    ),
    (
        {"camera": {"lookfrom": [0, 0, 3], "lookat": [0, 0, 0], "vup": [0, 0, 1], "shutter": [1, "x"]}},
        [("camera.shutter[1]", "expected a number"), ("camera.vup", "must not be parallel to the view direction")],
    ),
    (
        {"film": {"width": 9000, "height": 0}},
        [("film.height", "must be >= 1"), ("film.width", "must be at most 2048 (limit max_width)")],
    ),
    (
        {
            "materials": {"m": {}},
            "objects": [
                {"type": "box", "min": [0, 0, 0], "max": [0, 1, 1], "material": "m", "name": 5},
                {"type": "quad", "corner": [0, "x", 0], "edge1": [1, 0, 0], "edge2": [2, 0, 0], "material": "m"},
                {"type": "triangle", "vertices": [[0, 0, 0], [1, 1, 1], [2, 2, 2]], "material": "m", "velocity": 1},
                {"type": "mesh", "vertices": [[0, 0, 0], "x"], "material": "m"},
            ],
        },
        [
            ("objects[0].name", "expected a string"),
            ("objects[0].max[0]", "must be greater than min[0] = 0"),
            ("objects[1].corner[1]", "expected a number"),
            ("objects[1].edge2", "must not be parallel to edge1"),
            ("objects[2].velocity", "expected a point [x, y, z]"),
            ("objects[2].vertices", "collinear"),
            ("objects[3].vertices[1]", "expected a point [x, y, z]"),
            ("objects[3].faces", "required field 'faces' is missing (or give a 'file')"),
        ],
    ),
]


@pytest.mark.parametrize(("changes", "want"), INDEPENDENT, ids=[w[-1][0] for _, w in INDEPENDENT])
def test_error_every_independent_error_at_once(changes, want):
    errors = validate_scene(_scene(**changes))["errors"]
    assert [e["path"] for e in errors] == [path for path, _ in want], errors
    for (_, message), error in zip(want, errors, strict=True):
        assert message in error["message"], error


def test_error_scene_checks_beside_errors_elsewhere():
    """The primitive limit and (without load_scene's context) undefined materials, while the film is invalid."""
    objects = [{"type": "sphere", "center": [i, 0, 0], "radius": 1, "material": "m"} for i in range(3)]
    data = _scene(film={"width": 0}, materials={"n": {}}, objects=objects)
    with pytest.raises(ValidationError) as info:
        Scene.model_validate(data)
    assert [e["loc"] for e in info.value.errors()] == [("film", "width")] + [
        ("objects", i, "material") for i in range(3)
    ]
    errors = validate_scene(data, Limits(max_primitives=2))["errors"]
    assert [e["path"] for e in errors] == ["film.width", *(f"objects[{i}].material" for i in range(3))]
    data["materials"] = {"m": {"kd": "red"}}
    errors = validate_scene(data, Limits(max_primitives=2))["errors"]
    assert [e["path"] for e in errors] == ["film.width", "materials.m.kd", "objects"]
    assert errors[-1]["message"] == "3 primitives; must be at most 2 (limit max_primitives)"


def test_error_numbers_outside_float32_at_their_path():
    """The renderer computes in float32: 1e300 would be infinity there. The largest float32 is accepted."""
    too_big = "must be between -3.4e38 and 3.4e38 (the renderer computes in 32-bit floats)"
    sphere = {"type": "sphere", "center": [0, 0, -1e39], "radius": 1e300, "material": "m"}
    data = _scene(background=1e39, ambient=[0, 0, 1e39], materials={"m": {"shininess": -1e39}}, objects=[sphere])
    assert {e["path"]: e["message"] for e in validate_scene(data)["errors"]} == {
        "background": too_big,
        "ambient[2]": too_big,
        "materials.m.shininess": too_big,
        "objects[0].center[2]": too_big,
        "objects[0].radius": too_big,
    }
    sphere.update(center=[0, 0, -3.4e38], radius=3.4e38)
    scene, _ = load_scene(_scene(background=3.4e38, materials={"m": {}}, objects=[sphere]))
    assert scene.objects[0].radius == 3.4e38


# ---------------------------------------------------------------------------------------------
# Good scenes.


def test_example_every_documented_field_accepted():
    scene, _ = load_scene(EXAMPLE)
    assert scene.version == 1
    assert scene.name == "Cornell box"
    assert scene.camera.lookfrom == (0.0, 0.0, 3.9)
    assert scene.camera.vfov == 39.3
    assert scene.camera.focus_distance is None
    assert scene.camera.shutter == (0.0, 1.0)
    assert scene.film.filter.type == "box"
    assert scene.film.filter.radius == 0.5
    assert (scene.sampler.type, scene.sampler.spp, scene.sampler.max_level) == ("jittered", 16, 3)
    assert scene.render.integrator == "whitted"
    assert scene.render.min_weight == 0.001
    assert scene.ambient == (0.05, 0.05, 0.05)
    assert scene.fog.color == (0.5, 0.5, 0.5)
    glass = scene.materials["glass"]
    assert glass.kd == (0.0, 0.0, 0.0)
    assert glass.kt == (1.0, 1.0, 1.0)
    assert glass.fresnel is True
    assert scene.materials["brushed"].gloss == 200.0
    floor = scene.materials["floor"]
    assert floor.ka == (0.1, 0.1, 0.1)
    assert floor.texture.color1 == (0.8, 0.8, 0.8)
    assert isinstance(floor.bump, NoiseBump)
    assert floor.bump.strength == 0.2
    poster = scene.materials["poster"]
    assert isinstance(poster.texture, ImageTexture)
    assert poster.texture.scale == (2.0, 1.0)
    assert isinstance(poster.bump, ImageBump)
    assert poster.bump.file == "textures/height.png"
    light_types = [PointLight, DirectionalLight, SpotLight, QuadLight, DiskLight, SphereLight]
    assert [type(light) for light in scene.lights] == light_types
    assert scene.lights[0].intensity == (10.0, 10.0, 10.0)
    assert scene.lights[2].cutoff == 30.0
    assert [type(o) for o in scene.objects] == [Sphere, Plane, Quad, Disk, Box, Triangle, Mesh, Mesh]
    box, mesh = scene.objects[4], scene.objects[6]
    assert isinstance(box.material, Material)
    assert box.velocity == (0.0, 0.1, 0.0)
    assert box.transform.scale == (1.0, 1.0, 1.0)
    assert box.transform.rotate == (0.0, 20.0, 0.0)
    assert mesh.faces == [(0, 1, 2), (1, 3, 2)]
    assert mesh.smooth
    assert mesh.transform.scale == (1.0, 2.0, 1.0)
    assert scene.objects[7].file == "models/bunny.obj"
    assert scene.objects[7].vertices is None
    assert scene.objects[0].name == "glass ball"
    assert scene.material_for(scene.objects[0]) is glass and scene.material_for(box) is box.material


def test_example_values_are_float_tuples():
    scene, _ = load_scene(EXAMPLE)
    for value in (
        scene.camera.lookat,
        scene.materials["white"].kd,
        scene.objects[0].center,
        scene.background,
    ):
        assert isinstance(value, tuple)
        assert len(value) == 3
        assert all(type(c) is float for c in value)
    assert type(scene.objects[0].radius) is float
    assert type(scene.film.width) is int


def test_example_round_trip_through_json():
    scene, _ = load_scene(json.dumps(EXAMPLE))
    again, _ = load_scene(scene.model_dump_json(exclude_unset=True))
    assert again == scene


def test_defaults_of_a_minimal_scene():
    scene, warnings = load_scene(MINIMAL)
    assert warnings == []
    assert scene.camera.vup == (0.0, 1.0, 0.0)
    assert scene.camera.vfov == 40.0
    assert scene.camera.lens_radius == 0
    assert scene.camera.shutter == (0.0, 1.0)
    assert (scene.film.width, scene.film.height, scene.film.exposure) == (256, 256, 0.0)
    assert (scene.film.filter.type, scene.film.filter.radius) == ("box", 0.5)
    assert (scene.sampler.type, scene.sampler.spp, scene.sampler.threshold) == ("jittered", 16, 0.05)
    assert (scene.sampler.max_level, scene.sampler.jitter) == (3, False)
    r = scene.render
    assert (r.integrator, r.max_depth, r.min_weight, r.light_samples, r.seed) == ("whitted", 5, 0.001, 1, 0)
    assert scene.background == (0.0, 0.0, 0.0)
    assert scene.ambient == (0.0, 0.0, 0.0)
    assert scene.fog.density == 0.0
    assert scene.fog.color == (0.5, 0.5, 0.5)
    assert scene.materials == {}
    assert scene.lights == []
    assert scene.objects == []
    m = Material()
    assert m.kd == (0.5, 0.5, 0.5)
    assert m.ka is None
    assert m.shininess == 32
    assert m.ior == 1.5
    assert m.gloss is None


@pytest.mark.parametrize(("kind", "radius"), [("box", 0.5), ("tent", 1.0), ("gaussian", 1.5), ("mitchell", 2.0)])
def test_defaults_filter_radius_by_type(kind, radius):
    scene, _ = load_scene(_scene(film={"filter": {"type": kind}}))
    assert scene.film.filter.radius == radius
    assert "radius" not in scene.film.filter.model_fields_set  # filled in, not set by the user
    scene, _ = load_scene(_scene(film={"filter": {"type": kind, "radius": 3}}))
    assert scene.film.filter.radius == 3.0


@pytest.mark.parametrize(("kind", "spp"), [("center", 1), ("grid", 16), ("random", 16), ("adaptive", 16)])
def test_defaults_spp_by_sampler_type(kind, spp):
    scene, _ = load_scene(_scene(sampler={"type": kind}))
    assert scene.sampler.spp == spp


def test_accepts_single_number_for_rgb_and_scale_and_data_uri_files():
    data = _scene(
        background=0.25,
        materials={"m": {"kd": 1, "texture": {"type": "image", "file": "data:image/png;base64,AAAA"}}},
        objects=[{"type": "mesh", "file": "data:model/obj;base64,AAAA", "material": "m"}],
    )
    scene, _ = load_scene(data)
    assert scene.background == (0.25, 0.25, 0.25)
    assert scene.materials["m"].kd == (1.0, 1.0, 1.0)


def test_accepts_dict_text_bytes_and_path(tmp_path):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(EXAMPLE))
    scenes = [load_scene(src)[0] for src in (EXAMPLE, json.dumps(EXAMPLE), json.dumps(EXAMPLE).encode(), path)]
    assert all(s == scenes[0] for s in scenes)


@pytest.mark.parametrize("path", sorted(SCENES_DIR.glob("*.json")), ids=lambda p: p.name)
def test_example_scenes_of_the_repository_are_valid(path):
    report = validate_scene(path, assets=ASSET_DIR)  # their asset files too
    assert report["valid"], report["errors"]


def test_load_scene_str_path_as_in_the_readme(monkeypatch):
    """README: `load_scene("scenes/cornell_path.json")`; a str that is no JSON text is a path."""
    monkeypatch.chdir(SCENES_DIR.parent)
    scene, _ = load_scene("scenes/cornell_path.json")
    assert scene == load_scene(SCENES_DIR / "cornell_path.json")[0]
    assert load_scene(str(SCENES_DIR / "cornell_path.json"))[0] == scene
    assert validate_scene("scenes/whitted.json")["valid"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("scenes/nope.json", "cannot read scene file scenes/nope.json: no such file (and the text is not JSON either)"),
        ("cornell", "'cornell' is neither JSON (invalid JSON at line 1, column 1: Expecting value) nor the path of"),
        ("  ", "the scene text is empty: expected JSON {...} or the path of a scene file"),
        ('{"camera": }', "invalid JSON at line 1, column 12: Expecting value"),
        ("bad.json", "invalid JSON at line 1, column 2"),  # a file that exists, with a syntax error
    ],
)
def test_load_scene_text_neither_path_nor_json_says_so(tmp_path, monkeypatch, text, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.json").write_text("{camera: 1}")
    with pytest.raises(SceneError) as info:
        load_scene(text)
    (error,) = info.value.errors
    assert error["path"] == "" and error["message"].startswith(message), error


def test_validate_scene_report_of_a_good_scene():
    report = validate_scene(EXAMPLE)
    assert report["valid"] is True
    assert report["errors"] == []
    assert all(set(w) == {"path", "message"} for w in report["warnings"])


# ---------------------------------------------------------------------------------------------
# Limits.


def test_limits_primitive_count_at_objects():
    """A box counts 12 triangles, an inline mesh its faces, everything else 1."""
    mesh = {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]] * 5}
    box = {"type": "box", "min": [0, 0, 0], "max": [1, 1, 1]}
    sphere = {"type": "sphere", "center": [0, 0, 0], "radius": 1}
    objects = [{**o, "material": "m"} for o in (mesh, box, sphere)]
    data = _scene(materials={"m": {}}, objects=objects)
    load_scene(data, Limits(max_primitives=18))
    with pytest.raises(SceneError) as info:
        load_scene(data, Limits(max_primitives=17))
    assert info.value.errors == [
        {"path": "objects", "message": "18 primitives; must be at most 17 (limit max_primitives)"}
    ]


def test_limits_configurable_each_at_its_field():
    data = _scene(
        film={"width": 64, "height": 64},
        sampler={"type": "grid", "spp": 64},
        render={"max_depth": 9, "light_samples": 5},
    )
    load_scene(data)
    limits = Limits(max_width=32, max_height=32, max_spp=16, max_depth=8, max_light_samples=4)
    with pytest.raises(SceneError) as info:
        load_scene(data, limits)
    assert {e["path"]: e["message"] for e in info.value.errors} == {
        "film.width": "must be at most 32 (limit max_width)",
        "film.height": "must be at most 32 (limit max_height)",
        "sampler.spp": "must be at most 16 (limit max_spp)",
        "render.max_depth": "must be at most 8 (limit max_depth)",
        "render.light_samples": "must be at most 4 (limit max_light_samples)",
    }


def test_limits_pixels_at_the_height():
    """width x height past max_pixels is reported at the height, once each side is within its own limit."""
    data = _scene(film={"width": 11, "height": 10})
    assert validate_scene(data, Limits(max_pixels=110))["valid"]
    assert validate_scene(data, Limits(max_pixels=109))["errors"] == [
        {"path": "film.height", "message": "width x height = 110 pixels; must be at most 109 (limit max_pixels)"}
    ]


def test_limits_one_table_gives_the_defaults_and_the_tighter_of_two():
    """Limits is the table of tracer/limits.py: its defaults are the service's (2048 pixels wide, ...)."""
    from tracer.limits import LIMITS

    assert dataclasses.asdict(Limits()) == {limit.name: limit.default for limit in LIMITS}
    assert Limits().max_width == 2048 and Limits().max_spp == 4096
    a, b = Limits(max_width=100, max_spp=8), Limits(max_width=50, max_patches=7)
    assert a.tighter(b) == b.tighter(a) == Limits(max_width=50, max_spp=8, max_patches=7)
    assert Limits(max_depth=3).at_most("max_depth") == "must be at most 3 (limit max_depth)"


# ---------------------------------------------------------------------------------------------
# Warnings: settings that have no effect.

POINT = {"type": "point", "position": [0, 2, 0]}
SPHERE = {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}
WARNINGS = [
    (
        {"camera": {**MINIMAL["camera"], "shutter": [0, 0.5]}, "objects": [SPHERE]},
        "camera.shutter",
        "nothing moves",
    ),
    ({"camera": {**MINIMAL["camera"], "focus_distance": 3}}, "camera.focus_distance", "pinhole"),
    ({"sampler": {"threshold": 0.1}}, "sampler.threshold", "only the adaptive sampler"),
    ({"sampler": {"type": "random", "max_level": 2}}, "sampler.max_level", "only the adaptive sampler"),
    ({"sampler": {"jitter": True}}, "sampler.jitter", "only the adaptive sampler"),
    ({"render": {"light_samples": 4}, "lights": [POINT]}, "render.light_samples", "no area light"),
    ({"fog": {"color": 0.2}}, "fog.color", "density is 0"),
    ({"materials": {"m": {"ior": 1.3}}}, "materials.m.ior", "opaque"),
    ({"materials": {"m": {"fresnel": True}}}, "materials.m.fresnel", "neither reflects nor transmits"),
    ({"materials": {"m": {"gloss": 50}}}, "materials.m.gloss", "neither reflects nor transmits"),
    ({"materials": {"m": {"kd": [1.2, 0.5, 0.5]}}}, "materials.m.kd", "not energy conserving"),
    ({"objects": [{**SPHERE, "material": {"ior": 2}}]}, "objects[0].material.ior", "opaque"),
    ({"lights": [{**POINT, "intensity": 0}]}, "lights[0].intensity", "contributes nothing"),
    (
        {"lights": [{"type": "directional", "direction": [0, -1, 0], "irradiance": 0}]},
        "lights[0].irradiance",
        "zero",
    ),
    (
        {"lights": [{"type": "sphere", "center": [0, 2, 0], "radius": 1, "radiance": 0}]},
        "lights[0].radiance",
        "zero",
    ),
]


@pytest.mark.parametrize(("changes", "path", "message"), WARNINGS, ids=[w[1] for w in WARNINGS])
def test_warning_setting_without_effect(changes, path, message):
    _, warnings = load_scene(_scene(**{"materials": {"m": {}}, **changes}))
    assert [w["path"] for w in warnings] == [path]
    assert message in warnings[0]["message"]


@pytest.mark.parametrize(
    "changes",
    [
        {"camera": {**MINIMAL["camera"], "shutter": [0, 1]}, "objects": [{**SPHERE, "velocity": [1, 0, 0]}]},
        {"camera": {**MINIMAL["camera"], "lens_radius": 0.1, "focus_distance": 3}},
        {"sampler": {"type": "adaptive", "threshold": 0.1, "max_level": 4, "jitter": True}},
        {
            "render": {"light_samples": 4},
            "lights": [{"type": "disk", "center": [0, 2, 0], "normal": [0, -1, 0], "radius": 1}],
        },
        {"fog": {"density": 0.1, "color": 0.2}},
        {"materials": {"m": {"kd": 0, "kr": [0, 0, 0.5], "kt": [0, 0, 0.5], "ior": 1.3, "fresnel": True, "gloss": 50}}},
        {"materials": {"m": {"kr": 0.5, "fresnel": True, "gloss": 50, "kd": 0.5}}},
        {"camera": {**MINIMAL["camera"], "focus_distance": None}},
    ],
)
def test_warning_not_given_when_the_setting_has_an_effect(changes):
    _, warnings = load_scene(_scene(**{"materials": {"m": {}}, **changes}))
    assert warnings == []


# ---------------------------------------------------------------------------------------------
# Warnings: materials that render something other than what they were meant to be.

# the page's material presets (what "Add material" writes): none of them warns, and each is what its name says
PRESETS = json.loads((ROOT / "web" / "templates" / "materials.json").read_text())


def test_material_presets_are_the_sensible_ones():
    assert set(PRESETS) >= {"diffuse", "plastic", "mirror", "metal", "glass"}
    glass = PRESETS["glass"]["material"]
    assert glass["kd"] == 0
    assert glass["kr"] == glass["kt"] == 1
    assert glass["fresnel"] is True
    assert glass["ior"] > 1
    assert PRESETS["mirror"]["material"].get("kt", 0) == 0
    assert PRESETS["mirror"]["material"]["kr"] >= 0.8
    assert PRESETS["plastic"]["material"]["ks"] > 0
    assert PRESETS["plastic"]["material"].get("kr", 0) == 0


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_material_presets_give_no_warning(name):
    _, warnings = load_scene(_scene(materials={"m": PRESETS[name]["material"]}, objects=[SPHERE]))
    assert warnings == []


MATERIAL_WARNINGS = [
    # the first try: kt with the default kd 0.5 renders a grey, half-opaque ball
    ({"kt": 1, "ior": 1.5}, {"materials.m.kd": "half-opaque", "materials.m.kt": "without Fresnel"}),
    ({"kd": 0.3, "kr": 1, "kt": 1, "fresnel": True}, {"materials.m.kd": "half-opaque"}),
    ({"kd": 0, "kr": 0.1, "kt": 0.9}, {"materials.m.kt": "without Fresnel"}),
    ({"kd": 0, "kr": 1, "kt": 1, "ior": 1, "fresnel": True}, {"materials.m.ior": "nothing refracts"}),
    ({"kd": 0, "kt": 1, "fresnel": True}, {"materials.m.kr": "lost"}),
    ({"kd": 0.6, "kr": 0.6}, {"materials.m": "kd + kr + kt = 1.2 > 1"}),
    ({"kd": 0.5, "kr": 0.8, "kt": 0.8, "fresnel": True}, {"materials.m.kd": "half-opaque"}),
    ({"kd": [0.2, 0.2, 0.5], "kr": [0.7, 0.7, 0.7]}, {"materials.m": "= 1.2 > 1"}),
]


@pytest.mark.parametrize(("material", "want"), MATERIAL_WARNINGS, ids=[str(m[0]) for m in MATERIAL_WARNINGS])
def test_material_warning_for_a_combination(material, want):
    _, warnings = load_scene(_scene(materials={"m": material}, objects=[SPHERE]))
    got = {w["path"]: w["message"] for w in warnings}
    assert set(got) == set(want), got
    for path, words in want.items():
        assert words in got[path], got[path]


def test_material_warning_names_the_default_kd():
    _, warnings = load_scene(_scene(materials={"m": {"kt": 1, "ior": 1.5}}, objects=[SPHERE]))
    kd = next(w for w in warnings if w["path"] == "materials.m.kd")
    assert kd["message"].startswith("is 0.5 (the default) while kt = 1")


def test_material_warning_of_an_inline_material():
    _, warnings = load_scene(_scene(objects=[{**SPHERE, "material": {"kt": 1}}]))
    assert {w["path"] for w in warnings} == {"objects[0].material.kd", "objects[0].material.kt"}


def test_warnings_of_the_format_example():
    """The example in SCENE_FORMAT.md sets a shutter with nothing moving and adaptive-only settings."""
    data = copy.deepcopy(EXAMPLE)
    data["objects"][4]["velocity"] = [0, 0, 0]
    _, warnings = load_scene(data)
    paths = [w["path"] for w in warnings]
    assert paths == [
        "camera.shutter",
        "sampler.threshold",
        "sampler.max_level",
        "sampler.jitter",
        "fog.color",
    ]


# ---------------------------------------------------------------------------------------------
# JSON Schema.


def _nodes(node):
    if isinstance(node, dict):
        yield node
        for value in node.values():
            yield from _nodes(value)
    elif isinstance(node, list):
        for value in node:
            yield from _nodes(value)


def test_schema_is_json_and_names_every_type():
    schema = json.loads(json.dumps(scene_json_schema(), allow_nan=False))
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["type"] == "object"
    assert schema["additionalProperties"] is False
    objects = schema["properties"]["objects"]["items"]["discriminator"]["mapping"]
    lights = schema["properties"]["lights"]["items"]["discriminator"]["mapping"]
    assert set(objects) == {"sphere", "plane", "quad", "disk", "box", "triangle", "mesh"}
    assert set(lights) == {"point", "directional", "spot", "quad", "disk", "sphere"}
    text = json.dumps(schema)
    for tag in ("checker", "image", "noise", "box", "tent", "gaussian", "mitchell", "adaptive", "radiosity"):
        assert f'"{tag}"' in text


def test_schema_every_property_described_and_refs_resolve():
    schema = scene_json_schema()
    for node in _nodes(schema):
        for name, prop in node.get("properties", {}).items():
            assert prop.get("description"), name
        if "$ref" in node:
            assert node["$ref"].removeprefix("#/$defs/") in schema["$defs"]
        # constraints must be JSON Schema keywords (minimum, exclusiveMinimum...), not pydantic's names
        assert not {"ge", "gt", "le", "lt"} & set(node) or "properties" in node, node


def test_schema_rgb_accepts_a_single_number():
    kd = scene_json_schema()["$defs"]["Material"]["properties"]["kd"]
    assert [branch["type"] for branch in kd["anyOf"]] == ["number", "array"]
    assert kd["default"] == [0.5, 0.5, 0.5]


# ---------------------------------------------------------------------------------------------
# Assets.


def test_resolve_asset_inside_missing_absolute_escaping(tmp_path):
    assets = tmp_path / "assets"
    (assets / "models").mkdir(parents=True)
    (assets / "models" / "bunny.obj").write_text("v 0 0 0\n")
    (tmp_path / "secret.obj").write_text("v 0 0 0\n")
    (assets / "link.obj").symlink_to(tmp_path / "secret.obj")
    assert resolve_asset("models/bunny.obj", "objects[0].file", assets) == (assets / "models/bunny.obj").resolve()
    assert resolve_asset("models/../models/bunny.obj", "x", assets) == (assets / "models/bunny.obj").resolve()
    assert resolve_asset("data:model/obj;base64,AAAA", "x", assets) is None
    cases = {
        "missing.obj": "not found",
        "/etc/passwd": "absolute",
        "../secret.obj": "outside the asset folder",
        "link.obj": "outside the asset folder",
        "bad\x00name.obj": "cannot resolve",
    }
    for file, message in cases.items():
        with pytest.raises(SceneError) as info:
            resolve_asset(file, "objects[2].file", assets)
        (error,) = info.value.errors
        assert error["path"] == "objects[2].file" and message in error["message"], file


def test_resolve_asset_default_folder_is_scenes_assets():
    assert ASSET_DIR == ROOT / "scenes" / "assets"


def _mesh(file: str) -> dict:
    return {"type": "mesh", "file": file, "material": "m"}


def test_assets_missing_mesh_file_is_an_error_when_assets_are_resolved(tmp_path):
    data = _scene(materials={"m": {}}, objects=[_mesh("models/teapot.obj")])
    assert validate_scene(data)["valid"]  # the format alone: the file is the renderer's business
    report = validate_scene(data, assets=tmp_path)
    (error,) = report["errors"]
    assert error["path"] == "objects[0].file"
    assert error["message"].startswith(f"asset file 'models/teapot.obj' not found in the asset folder {tmp_path};")
    assert "--assets DIR" in error["message"]
    assert "data: URI" in error["message"]
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "teapot.obj").write_text(obj_grid(2))
    assert validate_scene(data, assets=tmp_path)["valid"]


def test_assets_errors_come_with_every_other_error(tmp_path):
    data = _scene(film={"width": 0}, materials={"m": {"kd": -1}}, objects=[_mesh("gone.obj")])
    paths = [e["path"] for e in validate_scene(data, assets=tmp_path)["errors"]]
    assert paths == ["film.width", "materials.m.kd", "objects[0].file"]


def test_assets_data_textures_that_are_not_images(tmp_path):
    """Five data: textures and bumps that are not images: each an error at its path, no Python repr."""
    (tmp_path / "notes.png").write_text("not a picture")
    files = {
        "a": ("texture", "data:image/png;base64,AAAA"),
        "b": ("texture", "data:text/plain,hello"),
        "c": ("bump", uri("image/png", b"GIF87a but not really")),
        "d": ("texture", obj_uri(1)),
        "e": ("bump", "data:image/png;base64,not base64!"),
        "f": ("texture", "notes.png"),
        "ok": ("texture", png_uri()),
    }
    materials = {name: {kind: {"type": "image", "file": file}} for name, (kind, file) in files.items()}
    data = _scene(materials=materials)
    assert validate_scene(data)["valid"]  # the format alone
    errors = validate_scene(data, assets=tmp_path)["errors"]
    assert [e["path"] for e in errors] == [f"materials.{n}.{kind}.file" for n, (kind, _) in files.items() if n != "ok"]
    not_image = "the data: URI is not a readable image (PNG or JPEG)"
    assert [e["message"] for e in errors[:4]] == [not_image, not_image, f"{not_image}: it is a GIF image", not_image]
    assert errors[4]["message"].startswith("the data: URI's data is not valid base64")
    assert errors[5]["message"] == "asset file 'notes.png' is not a readable image (PNG or JPEG)"
    assert all(no_repr(e["message"]) for e in errors)


def test_assets_an_eps_texture_is_not_valid():
    """The issue's case: an EPS "texture" was valid (Pillow reads its header) and failed in the worker (its
    pixels need Ghostscript, which would run a student's PostScript). Refused at validation, at its field."""
    eps = io.BytesIO()
    Image.new("RGB", (4, 2)).save(eps, format="EPS")
    texture = {"type": "image", "file": uri("application/postscript", eps.getvalue())}
    data = _scene(materials={"m": {"texture": texture}})
    assert validate_scene(data, assets=ASSET_DIR)["errors"] == [
        {
            "path": "materials.m.texture.file",
            "message": "the data: URI is not a readable image (PNG or JPEG): it is a PostScript (EPS) file",
        }
    ]


def test_assets_texture_pixels_limit_read_from_the_header():
    data = _scene(materials={"m": {"texture": {"type": "image", "file": uri("image/png", png_header_only(100, 30))}}})
    assert validate_scene(data, Limits(max_texture_pixels=3000), assets=ASSET_DIR)["valid"]  # pixels never decoded
    (error,) = validate_scene(data, Limits(max_texture_pixels=2999), assets=ASSET_DIR)["errors"]
    assert error == {
        "path": "materials.m.texture.file",
        "message": "the image is 100x30 = 3000 pixels; must be at most 2999 (limit max_texture_pixels)",
    }


def test_assets_texture_pixels_total_counts_each_distinct_image_once():
    """Every image of a scene (textures and bumps, of named and inline materials, data: URIs and files) counts
    towards the total, each distinct file once, from its header; the error names the image that crosses it."""
    a, b = uri("image/png", png_header_only(100, 30)), uri("image/png", png_header_only(50, 20))
    data = _scene(
        materials={
            "m": {"texture": {"type": "image", "file": a}},  # 3000
            "n": {"bump": {"type": "image", "file": a}},  # the same image again: not counted twice
            "p": {"texture": {"type": "image", "file": "bricks.png"}},  # 256 x 256 = 65536, from the asset folder
        },
        objects=[
            {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"bump": {"type": "image", "file": b}}}
        ],
    )
    total = 3000 + 65536 + 1000
    assert validate_scene(data, Limits(max_texture_pixels_total=total), assets=ASSET_DIR)["valid"]
    assert validate_scene(data, Limits(max_texture_pixels_total=1))["valid"]  # the format alone reads no header
    (error,) = validate_scene(data, Limits(max_texture_pixels_total=total - 1), assets=ASSET_DIR)["errors"]
    assert error == {
        "path": "objects[0].material.bump.file",
        "message": f"with this 50x20 image the scene's images come to {total} pixels; all of a scene's images "
        f"together must be at most {total - 1} (limit max_texture_pixels_total)",
    }
    (error,) = validate_scene(data, Limits(max_texture_pixels_total=68_000), assets=ASSET_DIR)["errors"]
    assert error["path"] == "materials.p.texture.file"
    assert "come to 68536 pixels" in error["message"]
    # an image past the limit of one image is reported at its own field, once
    errors = validate_scene(data, Limits(max_texture_pixels=3000, max_texture_pixels_total=4000), assets=ASSET_DIR)
    assert [e["path"] for e in errors["errors"]] == ["materials.p.texture.file"]
    assert (
        errors["errors"][0]["message"]
        == "the image is 256x256 = 65536 pixels; must be at most 3000 (limit max_texture_pixels)"
    )


def test_assets_a_6000_x_6000_png_is_refused_from_its_header_without_decoding():
    """A real blank 6000 x 6000 PNG in a data: URI (100 KB; 432 MB once decoded as float32) is refused by the
    service's limits at its field, and validating it holds no more than a few MB (traced allocations)."""
    import tracemalloc

    from server.core.settings import Settings
    from tests.support.assets import big_png_uri

    data = _scene(materials={"m": {"texture": {"type": "image", "file": big_png_uri()}}})
    tracemalloc.start()
    try:
        report = validate_scene(data, Settings().limits, assets=ASSET_DIR)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert report["errors"] == [
        {
            "path": "materials.m.texture.file",
            "message": "the image is 6000x6000 = 36000000 pixels; must be at most 16777216 (limit max_texture_pixels)",
        }
    ]
    assert peak < 20_000_000, f"validation held {peak / 1e6:.0f} MB"


def test_assets_mesh_triangles_count_against_the_primitive_limit(tmp_path):
    """A 3000-triangle data: OBJ and a mesh file count like inline meshes, at `objects`; a file past the limit
    on its own is refused at its own path."""
    (tmp_path / "grid.obj").write_text(obj_grid(10))  # 200 triangles
    objects = [_mesh(obj_uri(30, 50)), _mesh("grid.obj"), {"type": "sphere", "center": [0, 0, 0], "radius": 1}]
    data = _scene(materials={"m": {}}, objects=[{**o, "material": "m"} for o in objects])
    assert validate_scene(data, Limits(max_primitives=200))["valid"]  # the format alone cannot count them
    assert validate_scene(data, Limits(max_primitives=3201), assets=tmp_path)["valid"]
    errors = validate_scene(data, Limits(max_primitives=3000), assets=tmp_path)["errors"]
    assert errors == [
        {
            "path": "objects",
            "message": "3201 primitives (objects[0].file: 3000 triangles, objects[1].file: 200 triangles); "
            "must be at most 3000 (limit max_primitives)",
        }
    ]
    errors = validate_scene(data, Limits(max_primitives=200), assets=tmp_path)["errors"]
    assert errors == [
        {
            "path": "objects[0].file",
            "message": "the data: URI makes 3000 triangles; must be at most 200 (limit max_primitives)",
        }
    ]  # the scene's count waits for its objects to be valid


def test_assets_mesh_gltf_instances_are_refused_at_the_mesh_s_path():
    """1000 nodes of one 200-triangle glTF mesh: 200000 triangles, refused at objects[0].file from the node
    tree (nothing built), through the whole scene's validation."""
    data = _scene(materials={"m": {}}, objects=[{**_mesh(gltf_uri(gltf_instanced(1000))), "material": "m"}])
    errors = validate_scene(data, Limits(max_primitives=100_000), assets=ASSET_DIR)["errors"]
    assert errors == [
        {
            "path": "objects[0].file",
            "message": "the data: URI makes 200000 triangles (1000 mesh instances in its node tree); "
            "must be at most 100000 (limit max_primitives)",
        }
    ]


def test_assets_mesh_that_does_not_read_is_an_error_at_its_path():
    data = _scene(materials={"m": {}}, objects=[_mesh("data:model/obj,hello"), _mesh("bricks.png")])
    errors = validate_scene(data, assets=ASSET_DIR)["errors"]
    assert errors == [
        {"path": "objects[0].file", "message": "the data: URI holds no triangles"},
        {
            "path": "objects[1].file",
            "message": "could not read asset file 'bricks.png' as a mesh (OBJ, PLY, glTF): "
            "file_type 'png' not supported",
        },
    ]


def test_scene_adaptive_sampler_warns_about_spp_and_filter():
    from tracer.scene import validate_scene

    report = validate_scene(
        {
            "camera": {"lookfrom": [0, 0, 1], "lookat": [0, 0, 0]},
            "film": {"filter": {"type": "tent"}},
            "sampler": {"type": "adaptive", "spp": 4},
        }
    )
    assert report["valid"]
    assert {w["path"] for w in report["warnings"]} >= {"sampler.spp", "film.filter"}
