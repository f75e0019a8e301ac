"""Tests of tracer.assets: data: URIs, image headers and pixels, meshes (read once, read-only), messages.

The helpers at the top build real assets (a PNG encoded by Pillow, an OBJ grid of triangles) and are
used by the scene, CLI, API and grading tests too.
"""

from __future__ import annotations

import base64
import io
import shutil
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from tracer.assets import (
    ASSET_DIR,
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


def png_bytes(width: int = 4, height: int = 2, color=(255, 128, 0)) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", (width, height), color).save(buf, format="PNG")
    return buf.getvalue()


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose header says width x height and whose pixel data is junk: its size is readable, its
    pixels are not (and a decoder would need width x height x 3 bytes to hold them)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", b"junk") + chunk(b"IEND", b"")


def uri(media: str, raw: bytes) -> str:
    return f"data:{media};base64,{base64.b64encode(raw).decode()}"


def png_uri(width: int = 4, height: int = 2) -> str:
    return uri("image/png", png_bytes(width, height))


def obj_grid(nx: int, ny: int | None = None) -> str:
    """OBJ text of a grid of nx x ny quads in the z = 0 plane: 2 nx ny triangles."""
    ny = nx if ny is None else ny
    lines = [f"v {i} {j} 0" for j in range(ny + 1) for i in range(nx + 1)]
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i + 1  # OBJ indices start at 1
            lines += [f"f {a} {a + 1} {a + nx + 2}", f"f {a} {a + nx + 2} {a + nx + 1}"]
    return "\n".join(lines) + "\n"


def obj_uri(nx: int, ny: int | None = None) -> str:
    return uri("model/obj", obj_grid(nx, ny).encode())


def no_repr(message: str) -> bool:
    """A message for a student: no Python object repr (<_io.BytesIO object at 0x...>)."""
    return "<_io" not in message and " at 0x" not in message and "object at" not in message


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
    assert pixels.shape == (2, 2, 3) and pixels.dtype == np.float32
    np.testing.assert_allclose(pixels[0, 1], [1.0, 0.5029, 0.0], atol=1e-4)  # sRGB decoding, to 4 digits
    assert not pixels[1].any()


def big_png_uri(width: int = 6000, height: int = 6000) -> str:
    """A real PNG of width x height black pixels as a data: URI: it compresses to about 100 KB (a blank 6000 x
    6000 one), yet decoded it is 108 MB of 8-bit RGB and 432 MB of float32 linear RGB."""
    buf = io.BytesIO()
    Image.new("L", (width, height)).save(buf, format="PNG")
    return uri("image/png", buf.getvalue())


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
    assert message.startswith("the data: URI is not a readable image (PNG, JPEG, ...)") and no_repr(message)
    with pytest.raises(SceneError) as info:
        load_image(file, "materials.m.texture.file")
    (error,) = info.value.errors
    assert error["path"] == "materials.m.texture.file" and no_repr(error["message"])


def test_image_file_that_is_not_an_image(tmp_path):
    (tmp_path / "notes.png").write_text("not a picture")
    with pytest.raises(AssetError) as info:
        image_size("notes.png", tmp_path)
    assert info.value.message == "asset file 'notes.png' is not a readable image (PNG, JPEG, ...)"


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
    assert faces.shape == (12, 3) and verts.shape == (12, 3) and uv is None
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
