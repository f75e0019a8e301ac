"""Compilation of scenes into Warp arrays: boxes, transforms, meshes from files, assets."""

import base64
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tests.support.assets import no_repr
from tracer.kernels.compile import box_faces, compile_scene, transform_matrix
from tracer.rendering.raytree import ray_tree
from tracer.scene import ASSET_DIR, SceneError, Transform, load_scene


def scene_with(obj, **extra):
    d = {
        "camera": {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0]},
        "film": {"width": 8, "height": 8},
        "sampler": {"type": "center"},
        "materials": {"m": {"kd": 0.5}},
        "objects": [obj],
    }
    d.update(extra)
    return load_scene(d)[0]


def test_compile_transform_order_scale_rotate_translate():
    t = Transform(scale=[2, 1, 1], rotate=[0, 90, 0], translate=[0, 0, 5])
    m = transform_matrix(t)
    # (1,0,0) -> scale (2,0,0) -> rotate 90 about Y (0,0,-2) -> translate (0,0,3)
    assert_allclose(m @ [1, 0, 0, 1], [0, 0, 3, 1], atol=1e-12)


def test_compile_box_faces_point_outwards_even_when_mirrored():
    for t in (None, Transform(rotate=[10, 20, 30], scale=[1, -2, 0.5], translate=[1, 2, 3])):
        m = transform_matrix(t)
        centre = (m @ [0.5, 1, 1.5, 1])[:3]
        faces = box_faces([0, 0, 0], [1, 2, 3], t)
        assert len(faces) == 6
        for corner, e1, e2 in faces:
            mid = corner + 0.5 * (e1 + e2)
            assert np.dot(np.cross(e1, e2), mid - centre) > 0


def test_compile_mesh_file_and_data_uri_hit_the_same():
    obj = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n"
    uri = "data:model/obj;base64," + base64.b64encode(obj.encode()).decode()
    s1 = scene_with({"type": "mesh", "file": uri, "material": "m"})
    s2 = scene_with({"type": "triangle", "vertices": [[-1, -1, 0], [1, -1, 0], [0, 1, 0]], "material": "m"})
    t1, t2 = ray_tree(s1, 4, 4), ray_tree(s2, 4, 4)
    assert t1["nodes"][0]["t"] == pytest.approx(5.0103, rel=1e-4)  # pixel centre (4.5, 4.5), just off axis
    assert t1["nodes"][0]["t"] == t2["nodes"][0]["t"]
    assert t1["color"] == t2["color"]
    # the torus asset loads with its transform
    s3 = scene_with(
        {"type": "mesh", "file": "torus.obj", "material": "m", "smooth": True, "transform": {"rotate": [90, 0, 0]}}
    )
    cs = compile_scene(s3)
    assert cs.num_triangles > 1000
    tree = ray_tree(cs, 5, 4)  # the ring seen edge-on, just right of the centre
    assert tree["nodes"][0]["hit"] is not None


def test_compile_missing_or_escaping_asset_is_an_error_at_its_path():
    s = scene_with({"type": "mesh", "file": "no_such.obj", "material": "m"})
    with pytest.raises(SceneError) as e:
        compile_scene(s)
    assert e.value.errors[0]["path"] == "objects[0].file"
    with pytest.raises(SceneError) as e:
        load_scene(
            {
                "camera": {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0]},
                "materials": {"m": {}},
                "objects": [{"type": "mesh", "file": "../../pyproject.toml", "material": "m"}],
            }
        )
    assert e.value.errors[0]["path"] == "objects[0].file"
    tex = {"kd": 0.5, "texture": {"type": "image", "file": "missing.png"}}
    with pytest.raises(SceneError) as e:
        compile_scene(
            scene_with({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "t"}, materials={"t": tex})
        )
    assert e.value.errors[0]["path"] == "materials.t.texture.file"
    assert (ASSET_DIR / "uv_grid.png").is_file()


def test_compile_data_texture_that_is_not_an_image_is_an_error_at_its_path():
    """The renderer's own check (a scene validated for its format only): a message, not a Python repr."""
    tex = {"kd": 0.5, "texture": {"type": "image", "file": "data:image/png;base64,AAAA"}}
    s = scene_with({"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "t"}, materials={"t": tex})
    with pytest.raises(SceneError) as e:
        compile_scene(s)
    assert e.value.errors == [
        {"path": "materials.t.texture.file", "message": "the data: URI is not a readable image (PNG or JPEG)"}
    ]
    assert no_repr(str(e.value))


def test_compile_camera_basis():
    s = scene_with(
        {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"},
        camera={"lookfrom": [0, 0, 5], "lookat": [0, 0, 0], "vfov": 90},
    )
    cam = compile_scene(s).data.camera
    assert_allclose(cam.forward, [0, 0, -1])
    assert_allclose(cam.right, [1, 0, 0])
    assert_allclose(cam.up, [0, 1, 0])
    assert cam.h == pytest.approx(math.tan(math.radians(45)))


def test_compile_images_past_the_limits_are_refused_before_any_is_decoded():
    """The renderer counts a scene's images against the limits from their headers, as validation does, before
    it decodes one: a worker handed a 3000 x 2000 texture (which a scene validated without its assets never
    counted) refuses it at its field, holding a few MB (72 MB once decoded); within the limits, it decodes."""
    import tracemalloc

    from tests.support.assets import big_png_uri, png_uri
    from tracer.scene import Limits

    big, small = big_png_uri(3000, 2000), png_uri(4, 2)
    scene = scene_with(
        {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"texture": {"type": "image", "file": big}}},
        materials={"m": {"bump": {"type": "image", "file": small}}},
    )
    for limits, message in [
        (Limits(max_texture_pixels=5_999_999), "the image is 3000x2000 = 6000000 pixels; must be at most 5999999"),
        (Limits(max_texture_pixels_total=6_000_007), "the scene's images come to 6000008 pixels"),
    ]:
        tracemalloc.start()
        try:
            with pytest.raises(SceneError) as info:
                compile_scene(scene, limits=limits)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        (error,) = info.value.errors
        assert error["path"] == "objects[0].material.texture.file" and message in error["message"], error
        assert peak < 20_000_000, f"compiling held {peak / 1e6:.0f} MB before refusing"
    cs = compile_scene(scene, limits=Limits(max_texture_pixels_total=6_000_008))
    assert cs.data.tex_pixels.shape == (6_000_008,)
