"""Assets for the scene tests as data: URIs (PNG textures, OBJ grids, instanced glTF), shared by
tests/tracer/test_assets.py and the tests of the service that load them."""

from __future__ import annotations

import base64
import io
import json
import struct
import zlib

import numpy as np
from PIL import Image


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


def big_png_uri(width: int = 6000, height: int = 6000) -> str:
    """A real PNG of width x height black pixels as a data: URI: it compresses to about 100 KB (a blank 6000 x
    6000 one), yet decoded it is 108 MB of 8-bit RGB and 432 MB of float32 linear RGB."""
    buf = io.BytesIO()
    Image.new("L", (width, height)).save(buf, format="PNG")
    return uri("image/png", buf.getvalue())


def gltf_instanced(nodes: int, grid: int = 10, **tree) -> dict:
    """A glTF 2.0 (JSON, its buffer a data: URI) of `nodes` nodes side by side, each an instance of one mesh:
    a grid x grid plane of 2 grid² triangles. `tree` replaces parts of it."""
    xs = np.linspace(0.0, 1.0, grid + 1)
    verts = np.array([[x, y, 0.0] for y in xs for x in xs], np.float32)
    a = (np.arange(grid)[:, None] * (grid + 1) + np.arange(grid)[None, :]).reshape(-1)
    faces = np.concatenate([np.stack([a, a + 1, a + grid + 2], 1), np.stack([a, a + grid + 2, a + grid + 1], 1)])
    buf = faces.astype(np.uint32).tobytes() + verts.tobytes()
    return {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(buf), "uri": uri("application/octet-stream", buf)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": faces.size * 4},
            {"buffer": 0, "byteOffset": faces.size * 4, "byteLength": verts.nbytes},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5125, "count": faces.size, "type": "SCALAR"},
            {
                "bufferView": 1,
                "componentType": 5126,
                "count": len(verts),
                "type": "VEC3",
                "min": [0, 0, 0],
                "max": [1, 1, 0],
            },
        ],  # fmt: skip
        "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0}]}],
        "nodes": [{"mesh": 0, "translation": [2.0 * i, 0.0, 0.0]} for i in range(nodes)],
        "scenes": [{"nodes": list(range(nodes))}],
        **tree,
    }


def gltf_uri(tree: dict) -> str:
    return uri("model/gltf+json", json.dumps(tree).encode())
