"""Tests of tracer.assets: data: URIs, image headers and pixels, meshes (read once, read-only), messages.

The helpers at the top build real assets (a PNG encoded by Pillow, an OBJ grid of triangles) and are
used by the scene, CLI, API and grading tests too.
"""

from __future__ import annotations

import io
import json
import shutil
import tracemalloc

import numpy as np
import pytest
from PIL import Image

from tests.support.assets import gltf_instanced, gltf_uri, no_repr, obj_grid, obj_uri, png_bytes, png_header_only, uri
from tracer.assets import (
    ASSET_DIR,
    SRGB_TO_LINEAR,
    AssetError,
    data_uri,
    image_size,
    load_image,
    load_mesh_file,
    read_image,
    read_mesh,
    resolve,
)
from tracer.errors import SceneError

# ---------------------------------------------------------------------------------------------
# data: URIs.


def test_data_uri_base64_percent_encoded_and_whitespace():
    assert data_uri("data:model/obj;base64,diAwIDAgMAo=") == ("model/obj", b"v 0 0 0\n")
    assert data_uri("data:model/obj;base64,diAw\n IDAg MAo=") == ("model/obj", b"v 0 0 0\n")
    assert data_uri("data:model/obj,v%200%200%200") == ("model/obj", b"v 0 0 0")
    assert data_uri("data:,hello") == ("text/plain", b"hello")
    assert data_uri("data:Image/PNG;charset=x;BASE64,AAAA") == ("image/png", b"\0\0\0")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("data:image/png;base64", "there is no ','"),
        ("data:image/png;base64,%%%", "not valid base64"),
        ("data:image/png;base64,AAA", "not valid base64"),
        ("data:image/png;base64,", "holds no data"),
    ],
)
def test_data_uri_malformed_is_an_asset_error(text, message):
    with pytest.raises(AssetError, match=message):
        data_uri(text)


# ---------------------------------------------------------------------------------------------
# Images: the header for validation, the pixels for rendering.


def test_image_size_reads_the_header_only():
    header = uri("image/png", png_header_only(300, 200))
    assert image_size(header) == (300, 200)  # no pixel data at all, yet the size is known
    with pytest.raises(AssetError, match="could not be decoded as an image"):
        read_image(header)


def test_image_pixels_are_linear_rgb_top_row_first():
    img = Image.new("RGB", (2, 2), (0, 0, 0))
    img.putpixel((1, 0), (255, 188, 0))  # top right; sRGB 188 is linear 0.5
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    pixels = read_image(uri("image/png", buf.getvalue()))
    assert pixels.shape == (2, 2, 3)
    assert pixels.dtype == np.float32
    np.testing.assert_allclose(pixels[0, 1], [1.0, 0.5029, 0.0], atol=1e-4)  # sRGB decoding, to 4 digits
    assert not pixels[1].any()


def test_image_past_max_pixels_is_refused_from_its_header_before_decoding():
    """read_image checks the header's size against `max_pixels` before it decodes a pixel: a PNG with junk
    for pixels is refused for its size, not for its junk."""
    header = uri("image/png", png_header_only(300, 200))
    with pytest.raises(AssetError) as info:
        read_image(header, max_pixels=59_999)
    assert info.value.message == "the data: URI is 300x200 = 60000 pixels; at most 59999 here"
    with pytest.raises(AssetError, match="could not be decoded as an image"):
        read_image(header, max_pixels=60_000)  # within the limit: it is decoded, and its junk found
    with pytest.raises(SceneError) as info:
        load_image(header, "materials.m.bump.file", max_pixels=100)
    assert info.value.errors[0]["path"] == "materials.m.bump.file"


def test_image_pixels_go_through_the_srgb_curve_exactly():
    """The 256 codes of an 8-bit image are decoded through a table worked out once; each value is the sRGB
    curve's, computed per pixel in float32 as before the table, bit for bit."""
    codes = np.arange(256, dtype=np.uint8).reshape(16, 16)
    img = Image.fromarray(np.stack([codes, codes[::-1], codes.T], axis=-1))
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    pixels = read_image(uri("image/png", buf.getvalue()))
    rgb = np.asarray(img, dtype=np.float32) / 255.0
    curve = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4).astype(np.float32)
    np.testing.assert_array_equal(pixels, curve)


def test_image_past_pillow_s_decompression_bomb_guard_is_a_clear_error():
    """A header of 20000 x 20000 pixels trips Pillow's own guard (twice PIL.Image.MAX_IMAGE_PIXELS): a clear
    AssetError, never Pillow's exception."""
    bomb = uri("image/png", png_header_only(20_000, 20_000))
    with pytest.raises(AssetError) as info:
        image_size(bomb)
    assert info.value.message == "the data: URI has more than 178956970 pixels, more than any image may have here"
    with pytest.raises(SceneError):
        load_image(bomb, "materials.m.texture.file")


@pytest.mark.parametrize(
    "file",
    [
        "data:image/png;base64,AAAA",  # three zero bytes
        "data:text/plain,hello",
        uri("image/png", b"GIF87a but not really"),
        uri("image/jpeg", png_bytes()[:20]),  # a PNG cut inside its header
        obj_uri(1),
    ],
)
def test_image_not_an_image_says_so_without_a_repr(file):
    with pytest.raises(AssetError) as info:
        image_size(file)
    message = info.value.message
    assert message.startswith("the data: URI is not a readable image (PNG or JPEG)") and no_repr(message)
    with pytest.raises(SceneError) as info:
        load_image(file, "materials.m.texture.file")
    (error,) = info.value.errors
    assert error["path"] == "materials.m.texture.file" and no_repr(error["message"])


def test_image_file_that_is_not_an_image(tmp_path):
    (tmp_path / "notes.png").write_text("not a picture")
    with pytest.raises(AssetError) as info:
        image_size("notes.png", tmp_path)
    assert info.value.message == "asset file 'notes.png' is not a readable image (PNG or JPEG)"


# ---------------------------------------------------------------------------------------------
# Where files are.


def test_missing_file_names_the_folder_and_how_to_supply_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "assets").mkdir()
    with pytest.raises(AssetError) as info:
        resolve("models/teapot.obj", tmp_path / "assets")
    assert info.value.message == (
        "asset file 'models/teapot.obj' not found in the asset folder assets; copy it there, "
        "point the command line at the folder that holds it (--assets DIR), "
        "or embed the file in the scene as a data: URI"
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # a folder outside the working directory is named in full
    with pytest.raises(AssetError, match=f"in the asset folder {tmp_path / 'assets'};"):
        resolve("teapot.obj", tmp_path / "assets")


# ---------------------------------------------------------------------------------------------
# Meshes.


def test_mesh_data_uri_counts_its_triangles():
    verts, faces, uv = read_mesh(obj_uri(3, 2))
    assert faces.shape == (12, 3)
    assert verts.shape == (12, 3)
    assert uv is None
    assert faces.max() == 11  # 0-based


def test_mesh_read_once_and_read_only(tmp_path):
    shutil.copy(ASSET_DIR / "icosahedron.ply", tmp_path / "ico.ply")
    first = read_mesh("ico.ply", tmp_path)
    assert read_mesh("ico.ply", tmp_path) is first  # the cache: validation and compilation share it
    assert len(first[1]) == 80  # the icosahedron subdivided once
    with pytest.raises(ValueError, match="read-only"):
        first[0][0, 0] = 1.0
    (tmp_path / "ico.ply").write_text(obj_grid(1))  # a changed file (size, time) is read again
    with pytest.raises(AssetError, match="could not read asset file 'ico.ply' as a mesh"):
        read_mesh("ico.ply", tmp_path)


@pytest.mark.parametrize(
    ("file", "message"),
    [
        ("data:model/obj,hello", "the data: URI holds no triangles"),
        ("data:image/png;base64,AAAA", "unsupported data: URI type 'image/png'"),
        (uri("model/obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n"), "could not read the data: URI as a mesh"),
        (uri("model/gltf-binary", b"garbage"), "could not read the data: URI as a mesh"),
    ],
)
def test_mesh_that_cannot_be_read_says_so_at_its_path(file, message):
    with pytest.raises(SceneError) as info:
        load_mesh_file(file, "objects[2].file")
    (error,) = info.value.errors
    assert error["path"] == "objects[2].file" and message in error["message"] and no_repr(error["message"])


def test_mesh_gltf_instances_count_as_trimesh_builds_them():
    """Three nodes of one 200-triangle mesh are 600 triangles, placed by their translations; a node tree that
    names a node twice (or in a cycle) holds it once, as trimesh's scene graph does."""
    with pytest.raises(AssetError) as info:
        read_mesh(gltf_uri(gltf_instanced(3)), max_triangles=599)
    assert info.value.message == (
        "the data: URI makes 600 triangles (3 mesh instances in its node tree); "
        "must be at most 599 (limit max_primitives)"
    )
    verts, faces, _ = read_mesh(gltf_uri(gltf_instanced(3)), max_triangles=600)
    assert faces.shape == (600, 3)
    np.testing.assert_allclose(sorted({round(float(x)) for x in verts[:, 0]}), [0, 1, 2, 3, 4, 5])
    repeated = gltf_instanced(2, scenes=[{"nodes": [0, 0, 1]}])
    repeated["nodes"][0]["children"] = [1, 1]
    repeated["nodes"][1]["children"] = [1]
    with pytest.raises(AssetError, match=r"^the data: URI makes 400 triangles \(2 mesh instances"):
        read_mesh(gltf_uri(repeated), max_triangles=399)


def test_mesh_gltf_instancing_is_refused_before_anything_is_built_and_never_kept():
    """The issue's case: 1000 nodes sharing one 5000-triangle mesh, 5 million triangles from a data: URI of
    a few hundred KB (trimesh took the checker to 2.5 GB building them). The count from the node tree refuses
    it holding a few MB (tracemalloc: Python's and numpy's allocations), and the refused mesh is not cached."""
    from tracer import assets

    tree = gltf_instanced(1000, grid=50)  # 2 x 50² = 5000 triangles
    file = gltf_uri(tree)
    assert len(file) < 400_000
    tracemalloc.start()
    try:
        with pytest.raises(SceneError) as info:
            load_mesh_file(file, "objects[0].file", max_triangles=2_000_000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info.value.errors == [
        {
            "path": "objects[0].file",
            "message": "the data: URI makes 5000000 triangles (1000 mesh instances in its node tree); "
            "must be at most 2000000 (limit max_primitives)",
        }
    ]
    assert peak < 10_000_000, f"held {peak / 1e6:.0f} MB"
    assert assets._mesh_key(file, ASSET_DIR) not in assets._meshes


def test_mesh_gltf_accessors_past_their_bytes_are_refused_before_trimesh_allocates_them():
    """An accessor without a bufferView becomes zeros of its count in trimesh: 10⁹ VEC3 floats are 12 GB from
    a few bytes of JSON. The accessors' bytes are bounded by the triangle limit (128 bytes a triangle)."""
    tree = gltf_instanced(1)
    tree["accessors"].append({"componentType": 5126, "count": 10**9, "type": "VEC3"})
    with pytest.raises(AssetError) as info:
        read_mesh(gltf_uri(tree), max_triangles=2_000_000)
    assert info.value.message == (
        "the data: URI's glTF accessors hold 12000003852 bytes; at most 256000000 here "
        "(128 bytes per triangle of limit max_primitives)"
    )


def test_mesh_gltf_images_are_not_decoded(monkeypatch):
    """A glTF's images are dropped before trimesh reads it (it would open them with Pillow in any format):
    an EPS image inside a glTF never reaches Pillow."""
    import PIL.Image

    opened = []
    monkeypatch.setattr(PIL.Image, "open", lambda *a, **k: opened.append(a) or pytest.fail("Pillow opened it"))
    tree = gltf_instanced(1, images=[{"uri": uri("application/postscript", b"%!PS-Adobe-3.0 EPSF-3.0\n")}],
                          textures=[{"source": 0}],
                          materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}])  # fmt: skip
    tree["meshes"][0]["primitives"][0]["material"] = 0
    _, faces, _ = read_mesh(gltf_uri(tree))
    assert len(faces) == 200
    assert opened == []


def test_mesh_cache_is_bounded_in_bytes(tmp_path, monkeypatch):
    """Past MESH_CACHE_BYTES the oldest meshes go; the one just read stays (validation, then compilation)."""
    from tracer import assets

    monkeypatch.setattr(assets, "_meshes", type(assets._meshes)())
    monkeypatch.setattr(assets, "MESH_CACHE_BYTES", 10_000)
    first, second = obj_uri(20), obj_uri(21)  # 441 and 484 vertices: about 20 KB each
    read_mesh(first)
    read_mesh(second)
    assert list(assets._meshes) == [assets._mesh_key(second, ASSET_DIR)]


def test_mesh_gltf_file_s_buffers_stay_inside_the_asset_folder(tmp_path):
    """A .gltf file's buffer beside it is read (the file is read as bytes, its images dropped, and its buffers
    through trimesh's resolver of its folder); one reached by '..' outside that folder is refused."""
    tree = gltf_instanced(2)
    raw = data_uri(tree["buffers"][0]["uri"])[1]
    (tmp_path / "assets" / "models").mkdir(parents=True)
    (tmp_path / "assets" / "models" / "plane.bin").write_bytes(raw)
    (tmp_path / "outside.bin").write_bytes(raw)
    tree["buffers"][0]["uri"] = "plane.bin"
    (tmp_path / "assets" / "models" / "plane.gltf").write_text(json.dumps(tree))
    assert len(read_mesh("models/plane.gltf", tmp_path / "assets")[1]) == 400
    tree["buffers"][0]["uri"] = "../../outside.bin"
    (tmp_path / "assets" / "models" / "out.gltf").write_text(json.dumps(tree))
    with pytest.raises(AssetError, match=r"as a mesh \(OBJ, PLY, glTF\): '../../outside.bin' escapes resolver root"):
        read_mesh("models/out.gltf", tmp_path / "assets")


def image_bytes(fmt: str, width: int = 4, height: int = 2) -> bytes:
    """A width x height orange image that Pillow writes (and reads back) in format `fmt`."""
    buf = io.BytesIO()
    Image.new("RGB", (width, height), (255, 128, 0)).save(buf, format=fmt)
    return buf.getvalue()


@pytest.mark.parametrize(
    ("fmt", "told"),
    [
        ("EPS", ": it is a PostScript (EPS) file"),  # Pillow reads its header; its pixels through Ghostscript
        ("BMP", ": it is a BMP image"),
        ("TIFF", ": it is a TIFF image"),
        ("GIF", ": it is a GIF image"),
        ("WEBP", ": it is a WebP image"),
        ("ICO", ": it is an ICO icon"),
        ("TGA", ""),  # no magic bytes of its own
        ("PPM", ""),
    ],
)
def test_image_formats_other_than_png_and_jpeg_are_refused_by_their_first_bytes(fmt, told, tmp_path, monkeypatch):
    """Every one is an image Pillow reads (and so was a valid texture); now it never reaches Pillow, from a
    data: URI (whatever its media type says) or a file (whatever its suffix says)."""
    raw = image_bytes(fmt)
    assert Image.open(io.BytesIO(raw)).size == (4, 2)
    (tmp_path / "texture.png").write_bytes(raw)
    monkeypatch.setattr(Image, "open", lambda *a, **k: pytest.fail("Pillow opened it"))
    with pytest.raises(AssetError) as info:
        image_size(uri("image/png", raw))
    assert info.value.message == f"the data: URI is not a readable image (PNG or JPEG){told}"
    with pytest.raises(SceneError) as info:
        load_image("texture.png", "materials.m.bump.file", tmp_path)
    assert info.value.errors == [
        {
            "path": "materials.m.bump.file",
            "message": f"asset file 'texture.png' is not a readable image (PNG or JPEG){told}",
        }
    ]


def test_image_png_and_jpeg_are_read():
    assert image_size(uri("image/png", image_bytes("PNG", 5, 3))) == (5, 3)
    pixels = read_image(uri("image/jpeg", image_bytes("JPEG", 8, 8)))
    assert pixels.shape == (8, 8, 3)
    np.testing.assert_allclose(pixels[4, 4], SRGB_TO_LINEAR[[255, 128, 0]], atol=0.02)  # JPEG's loss
