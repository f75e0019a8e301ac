"""Asset files: meshes and images, from the asset folder or from data: URIs, read in this one place.

A scene names an asset either by a path relative to the asset folder (scenes/assets unless the CLI is
given `--assets DIR`) or by a data: URI (RFC 2397: `data:<media type>[;base64],<data>`) that holds
the file itself. A path never reaches outside the folder, after '..' and symbolic links are resolved.

Validation (tracer/scene/) resolves every asset: an image's header is read (format and size, no
pixels decoded) and a mesh is read and its triangles counted against the primitive limit. Compiling
(tracer/kernels/compile.py) reads the same files through the same functions, so the two never disagree.

Functions that take a JSON `path` raise SceneError at that path; the others raise AssetError, whose
message the caller places at the field it checks.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import io
import json
import os
import posixpath
import re
import struct
import threading
from collections import OrderedDict
from pathlib import Path
from typing import cast
from urllib.parse import unquote_to_bytes

import numpy as np

from tracer.errors import FLOAT32_MAX, SceneError

ASSET_DIR = Path(__file__).resolve().parent.parent / "scenes" / "assets"
IMAGE_FORMATS = {"PNG": (b"\x89PNG\r\n\x1a\n",), "JPEG": (b"\xff\xd8\xff",)}  # the images read: Pillow format -> magic
IMAGE_KINDS = "PNG or JPEG"  # ... as a student is told
OTHER_FORMATS = {  # what a file that is not one of them is, by its first bytes, to say so
    b"GIF87a": "a GIF image", b"GIF89a": "a GIF image", b"BM": "a BMP image", b"II*\x00": "a TIFF image",
    b"MM\x00*": "a TIFF image", b"%!PS": "a PostScript (EPS) file", b"\xc5\xd0\xd3\xc6": "a PostScript (EPS) file",
    b"%PDF": "a PDF file", b"v/1\x01": "an OpenEXR image", b"\x00\x00\x01\x00": "an ICO icon",
}  # fmt: skip
MESH_TYPES = {  # data: URI media type -> trimesh file type
    "model/obj": "obj",
    "text/plain": "obj",
    "model/gltf-binary": "glb",
    "model/gltf+json": "gltf",
    "application/ply": "ply",
    "model/ply": "ply",
}
MESH_CACHE_SIZE = 16  # meshes kept read (validation and compilation read each one once)
MESH_CACHE_BYTES = 512 << 20  # ... and their arrays' bytes together, past which the oldest go (the newest stays)
GLTF_ACCESSOR_BYTES = 128  # a glTF's accessors may hold this many bytes per triangle a scene may have
GLTF_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}  # componentType -> bytes
GLTF_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
GLTF_TRIANGLES, GLTF_STRIP, GLTF_FAN = 4, 5, 6  # a primitive's modes that make triangles

MeshData = tuple[np.ndarray, np.ndarray, np.ndarray | None]  # vertices (n, 3), faces (m, 3), uvs (n, 2) or None


class AssetError(ValueError):
    """An asset that cannot be used; the message says why (the caller knows the JSON path)."""

    def __init__(self, message: str):
        self.message = message
        super().__init__(message)


def _at(path: str, exc: AssetError) -> SceneError:
    return SceneError([{"path": path, "message": exc.message}])


def _reason(exc: BaseException) -> str:
    """A library's error message without the object reprs some put in it (<_io.BytesIO object at 0x...>)."""
    text = re.sub(r"\s*<[^<>]* at 0x[0-9a-fA-F]+>", "", str(exc)).strip()
    return text or type(exc).__name__


def folder_name(asset_dir: Path) -> str:
    """The asset folder as a user would type it: relative to the working directory when inside it."""
    folder = Path(asset_dir).resolve()
    try:
        return str(folder.relative_to(Path.cwd().resolve())) or "."
    except ValueError:
        return str(folder)


# ---------------------------------------------------------------------------------------------
# Where an asset is.


def path_problem(file: str) -> str | None:
    """What is wrong with `file` as an asset path, judged from the text alone (None: nothing)."""
    if file.startswith("data:"):
        return None
    posix = file.replace("\\", "/")
    if not posix:
        return "must not be empty"
    if posix.startswith("/") or re.match(r"[A-Za-z]:", posix):
        return "must be a path relative to the asset folder, not an absolute path"
    if posixpath.normpath(posix).split("/")[0] == "..":
        return "must not reach outside the asset folder ('..')"
    return None


def resolve(file: str, asset_dir: Path = ASSET_DIR) -> Path | None:
    """The real path of asset `file` inside `asset_dir`; None for a data: URI. Raises AssetError."""
    if file.startswith("data:"):
        return None
    problem = path_problem(file)
    if problem:
        raise AssetError(problem)
    try:
        root = Path(asset_dir).resolve()
        target = (root / file).resolve()
        inside, exists = target.is_relative_to(root), target.is_file()
    except (OSError, ValueError, RuntimeError) as e:  # a NUL byte, a symbolic link loop, a long name
        raise AssetError(f"cannot resolve asset file '{file}': {e}") from None
    if not inside:
        raise AssetError("must not reach outside the asset folder")
    if not exists:
        raise AssetError(
            f"asset file '{file}' not found in the asset folder {folder_name(root)}; copy it there, "
            "point the command line at the folder that holds it (--assets DIR), "
            "or embed the file in the scene as a data: URI"
        )
    return target


def resolve_asset(file: str, path: str, asset_dir: Path = ASSET_DIR) -> Path | None:
    """`resolve`, raising SceneError at JSON path `path`."""
    try:
        return resolve(file, asset_dir)
    except AssetError as e:
        raise _at(path, e) from None


def data_uri(uri: str) -> tuple[str, bytes]:
    """(media type, bytes) of a data: URI. Raises AssetError when it is malformed or empty."""
    header, comma, payload = uri[len("data:") :].partition(",")
    if not comma:
        raise AssetError("a data: URI must be data:<media type>;base64,<data> (there is no ',')")
    params = [p.strip().lower() for p in header.split(";")]
    media = params[0] or "text/plain"
    if "base64" in params[1:]:
        try:
            raw = base64.b64decode("".join(payload.split()), validate=True)
        except (binascii.Error, ValueError) as e:
            reason = _reason(e)
            raise AssetError(f"the data: URI's data is not valid base64: {reason[:1].lower()}{reason[1:]}") from None
    else:
        raw = unquote_to_bytes(payload)
    if not raw:
        raise AssetError("the data: URI holds no data")
    return media, raw


def _source(file: str, asset_dir: Path) -> tuple[str, Path | io.BytesIO, str]:
    """(how to name it in a message, what to open, media type or '') of an asset."""
    if file.startswith("data:"):
        media, raw = data_uri(file)
        return "the data: URI", io.BytesIO(raw), media
    real = resolve(file, asset_dir)
    assert real is not None, "resolve returns None for a data: URI alone"
    return f"asset file '{file}'", real, ""


# ---------------------------------------------------------------------------------------------
# Images.


def image_format(head: bytes) -> str | None:
    """The format of IMAGE_FORMATS that a file's first bytes are the magic of (None: none of them)."""
    return next((name for name, magics in IMAGE_FORMATS.items() if head.startswith(magics)), None)


def other_format(head: bytes) -> str | None:
    """What a file of these first bytes is, when they are the magic of a format of OTHER_FORMATS ("a GIF
    image"; None: not known)."""
    if head.startswith(b"RIFF") and head[8:12] == b"WEBP":
        return "a WebP image"
    return next((name for magic, name in OTHER_FORMATS.items() if head.startswith(magic)), None)


def _not_allowed(what: str, head: bytes) -> AssetError:
    other = other_format(head)
    return AssetError(f"{what} is not a readable image ({IMAGE_KINDS})" + (f": it is {other}" if other else ""))


def _open_image(file: str, asset_dir: Path):
    """(how to name it, the image with its header read and no pixels decoded). Only PNG and JPEG are opened,
    told by their magic bytes before Pillow sees the file (and Pillow told to try no other format): Pillow
    reads dozens, some through other programs (EPS through Ghostscript), none of which a texture needs.
    Raises AssetError."""
    from PIL import Image, UnidentifiedImageError

    what, src, _ = _source(file, asset_dir)
    if isinstance(src, Path):
        try:
            with open(src, "rb") as f:
                head = f.read(16)
        except OSError as e:
            raise AssetError(f"cannot read {what}: {e.strerror}") from None
    else:
        head = src.getvalue()[:16]
    if image_format(head) is None:
        raise _not_allowed(what, head)
    try:
        img = Image.open(src, formats=list(IMAGE_FORMATS))  # reads the header only
    except UnidentifiedImageError:  # no format Pillow knows (its message names a temporary object)
        raise AssetError(f"{what} is not a readable image ({IMAGE_KINDS})") from None
    except Image.DecompressionBombError:  # Pillow's own guard, far past any limit of ours: a clear word, not its own
        most = 2 * (Image.MAX_IMAGE_PIXELS or 0)
        raise AssetError(f"{what} has more than {most} pixels, more than any image may have here") from None
    except Exception as e:  # a truncated header, an unreadable file
        raise AssetError(f"{what} is not a readable image ({IMAGE_KINDS}): {_reason(e)}") from None
    width, height = img.size
    if width < 1 or height < 1:
        img.close()
        raise AssetError(f"{what} is an empty image ({width}x{height} pixels)")
    return what, img


def image_size(file: str, asset_dir: Path = ASSET_DIR) -> tuple[int, int]:
    """(width, height) of an image asset from its header, no pixels decoded. Raises AssetError."""
    _, img = _open_image(file, asset_dir)
    with img:
        return img.size


def _srgb_table() -> np.ndarray:
    """The linear value of each 8-bit sRGB code, in float32: the sRGB curve (IEC 61966-2-1) worked out once
    for the 256 codes instead of for every pixel."""
    rgb = np.arange(256, dtype=np.float32) / 255.0
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4).astype(np.float32)


SRGB_TO_LINEAR = _srgb_table()


def read_image(file: str, asset_dir: Path = ASSET_DIR, max_pixels: int | None = None) -> np.ndarray:
    """An image asset as linear RGB float32, shape (height, width, 3), top row first; one of more than
    `max_pixels` pixels (read from its header) is refused before anything is decoded. Raises AssetError.
    Decoded, a pixel takes 3 bytes (8-bit RGB) and then 12 (the float32 result)."""
    what, img = _open_image(file, asset_dir)
    with img:
        width, height = img.size
        if max_pixels is not None and width * height > max_pixels:
            raise AssetError(f"{what} is {width}x{height} = {width * height} pixels; at most {max_pixels} here")
        try:
            codes = np.asarray(img.convert("RGB"))
        except Exception as e:  # truncated or corrupt pixel data
            raise AssetError(f"{what} could not be decoded as an image: {_reason(e)}") from None
    return SRGB_TO_LINEAR[codes]


def load_image(file: str, path: str, asset_dir: Path = ASSET_DIR, max_pixels: int | None = None) -> np.ndarray:
    """`read_image`, raising SceneError at JSON path `path`."""
    try:
        return read_image(file, asset_dir, max_pixels)
    except AssetError as e:
        raise _at(path, e) from None


# ---------------------------------------------------------------------------------------------
# Meshes.

_meshes: OrderedDict[tuple, tuple] = OrderedDict()
_meshes_lock = threading.Lock()


def _mesh_key(file: str, asset_dir: Path) -> tuple:
    if file.startswith("data:"):
        return ("data", hashlib.sha256(file.encode()).hexdigest())
    real = resolve(file, asset_dir)
    assert real is not None, "resolve returns None for a data: URI alone"
    st = os.stat(real)
    return ("file", str(real), st.st_mtime_ns, st.st_size)


def _too_many(what: str, triangles: int, most: int, how: str = "") -> AssetError:
    return AssetError(f"{what} makes {triangles} triangles{how}; must be at most {most} (limit max_primitives)")


def _glb_parts(raw: bytes) -> tuple[bytes, bytes]:
    """(the JSON chunk, the chunks after it) of a GLB file (glTF 2.0's binary container). Raises ValueError."""
    if len(raw) < 20 or raw[:4] != b"glTF":
        raise ValueError("not a GLB file (it does not start with 'glTF')")
    length, kind = struct.unpack_from("<I4s", raw, 12)
    if kind != b"JSON" or 20 + length > len(raw):
        raise ValueError("a GLB file's first chunk must be its JSON")
    return raw[20 : 20 + length], raw[20 + length :]


def _glb(tree: dict, rest: bytes) -> bytes:
    """A GLB file of JSON `tree` and the binary chunks `rest` (the JSON padded with spaces to 4 bytes)."""
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    return (
        struct.pack("<4sII", b"glTF", 2, 20 + len(text) + len(rest))
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + rest
    )


def _gltf_count(tree: dict) -> tuple[int, int, int]:
    """(triangles, mesh instances, bytes of the accessors) that trimesh makes of a glTF's JSON, counted before
    anything is built: each node reachable from the scene's roots once (as trimesh's scene graph holds it,
    whatever the node tree repeats), each of its mesh's primitives' triangles (from its index accessor's
    count, or its POSITION accessor's), and every accessor's count x components x bytes (trimesh makes an
    array of each; one without a bufferView is zeros of that size). Raises KeyError, IndexError, TypeError or
    ValueError (or AttributeError) for a malformed tree."""
    accessors = tree.get("accessors", [])
    data = sum(
        _count(a["count"]) * GLTF_COMPONENTS[a["type"]] * GLTF_COMPONENT_BYTES[a["componentType"]] for a in accessors
    )
    per_mesh = []
    for mesh in tree.get("meshes", []):
        n = 0
        for p in mesh["primitives"]:
            mode = p.get("mode", GLTF_TRIANGLES)
            items = _count(accessors[p["indices"] if "indices" in p else p["attributes"]["POSITION"]]["count"])
            n += items // 3 if mode == GLTF_TRIANGLES else max(items - 2, 0) if mode in (GLTF_STRIP, GLTF_FAN) else 0
        per_mesh.append(n)
    nodes = tree.get("nodes", [])
    roots = tree["scenes"][tree.get("scene", 0)].get("nodes", []) if "scenes" in tree else []
    seen, todo, triangles, instances = set(), list(roots), 0, 0
    while todo:
        i = todo.pop()
        if i in seen:
            continue
        seen.add(i)
        node = nodes[i]
        todo += node.get("children", [])
        if "mesh" in node:
            triangles += per_mesh[node["mesh"]]
            instances += 1
    return triangles, instances, data


def _count(n) -> int:
    if not isinstance(n, int) or isinstance(n, bool) or n < 0:
        raise ValueError(f"an accessor's count must be a whole number >= 0, not {n!r}")
    return n


def _checked_gltf(raw: bytes, kind: str, what: str, max_triangles: int | None) -> bytes:
    """A glTF (`kind` gltf or glb) checked against the limits before trimesh builds anything of it, returned
    without its images (trimesh would decode them with Pillow, in any format it knows; the renderer reads no
    glTF material). Raises AssetError."""
    try:
        text, rest = _glb_parts(raw) if kind == "glb" else (raw, b"")
        tree = json.loads(text)
        if not isinstance(tree, dict):
            raise ValueError("its JSON must be an object")
        triangles, instances, data = _gltf_count(tree)
    except (AttributeError, KeyError, IndexError, TypeError, ValueError, RecursionError, struct.error) as e:
        raise AssetError(f"could not read {what} as a mesh (glTF): {type(e).__name__}: {_reason(e)}") from None
    if max_triangles is not None:
        if triangles > max_triangles:
            raise _too_many(what, triangles, max_triangles, f" ({instances} mesh instances in its node tree)")
        if data > GLTF_ACCESSOR_BYTES * max(max_triangles, 1):
            most = GLTF_ACCESSOR_BYTES * max(max_triangles, 1)
            raise AssetError(f"{what}'s glTF accessors hold {data} bytes; at most {most} here ({GLTF_ACCESSOR_BYTES} "
                             "bytes per triangle of limit max_primitives)")  # fmt: skip
    tree.pop("images", None)
    return _glb(tree, rest) if kind == "glb" else json.dumps(tree).encode()


def import_mesh_reader() -> None:
    """Import the mesh reader (trimesh, and the parts of scipy it takes) now: 0.8-1.5 s and 60 MB, paid by a
    process's first scene with a mesh file otherwise (a render worker's, a checking process's: the texture
    lesson's first panel waited 3 s for it, issue #25). The service's processes call it as they start."""
    import trimesh  # noqa: F401


def _parse_mesh(file: str, asset_dir: Path, max_triangles: int | None = None) -> MeshData:
    what, src, media = _source(file, asset_dir)
    if isinstance(src, Path):
        kind = src.suffix.lower().lstrip(".")
    else:
        kind = MESH_TYPES.get(media)
        if kind is None:
            raise AssetError(
                f"unsupported data: URI type '{media}' (expected model/obj, model/ply or model/gltf-binary)"
            )
    checked = None
    if kind in ("gltf", "glb"):  # counted before trimesh is even imported (60 MB of a checking process)
        try:
            raw = src.read_bytes() if isinstance(src, Path) else src.getvalue()
        except OSError as e:
            raise AssetError(f"cannot read {what}: {e.strerror}") from None
        checked = _checked_gltf(raw, kind, what, max_triangles)
    import trimesh
    import trimesh.resolvers  # loaded with trimesh; named for the type checker

    try:
        if checked is not None:
            resolver = None
            if isinstance(src, Path):  # its buffers beside it: trimesh refuses any outside the file's folder
                resolver = trimesh.resolvers.FilePathResolver(str(src))
            tm = trimesh.load(io.BytesIO(checked), file_type=kind, resolver=resolver, force="mesh", process=False)
        elif isinstance(src, Path):
            tm = trimesh.load(str(src), force="mesh", process=False)
        else:
            tm = trimesh.load(src, file_type=kind, force="mesh", process=False)
        tm = cast(trimesh.Trimesh, tm)  # force="mesh": a Trimesh (load is annotated with their base, Geometry)
        verts = np.asarray(tm.vertices, dtype=np.float64)
        faces = np.asarray(tm.faces, dtype=np.int64).reshape(-1, 3)
    except AssetError:
        raise
    except Exception as e:  # a broken asset is the user's error, not a crash
        raise AssetError(f"could not read {what} as a mesh (OBJ, PLY, glTF): {_reason(e)}") from None
    if len(faces) == 0:
        raise AssetError(f"{what} holds no triangles")
    if max_triangles is not None and len(faces) > max_triangles:
        raise _too_many(what, len(faces), max_triangles)
    if faces.min() < 0 or faces.max() >= len(verts):
        raise AssetError(f"{what} has faces whose vertex indices are out of range ({len(verts)} vertices)")
    if not np.all(np.abs(verts) <= FLOAT32_MAX):
        raise AssetError(f"{what} has vertex coordinates that are not finite 32-bit floats")
    uv = getattr(getattr(tm, "visual", None), "uv", None)
    uv = np.asarray(uv, dtype=np.float64) if uv is not None and len(uv) == len(verts) else None
    for a in (verts, faces, uv):  # shared by every caller through the cache
        if a is not None:
            a.setflags(write=False)
    return verts, faces, uv


def _nbytes(mesh: MeshData) -> int:
    return sum(a.nbytes for a in mesh if a is not None)


def read_mesh(file: str, asset_dir: Path = ASSET_DIR, max_triangles: int | None = None) -> MeshData:
    """Vertices (n, 3), faces (m, 3) and per-vertex uvs (or None) of an OBJ/PLY/glTF asset, read-only
    arrays. A mesh of more than `max_triangles` triangles (None: any) is refused, a glTF's from its JSON
    before anything is built (its nodes instance its meshes), and never kept. The last few meshes read are
    kept (at most MESH_CACHE_SIZE, and MESH_CACHE_BYTES together unless it is the one just read), keyed by
    content (a data: URI) or path, time and size. Raises AssetError."""
    try:
        key = _mesh_key(file, asset_dir)
    except OSError as e:
        raise AssetError(f"cannot read asset file '{file}': {e.strerror}") from None
    with _meshes_lock:
        mesh = _meshes.get(key)
        if mesh is not None:
            _meshes.move_to_end(key)
    if mesh is not None:
        if max_triangles is not None and len(mesh[1]) > max_triangles:  # kept when a looser limit read it
            raise _too_many(_source_name(file), len(mesh[1]), max_triangles)
        return mesh
    mesh = _parse_mesh(file, asset_dir, max_triangles)
    with _meshes_lock:
        _meshes[key] = mesh
        while len(_meshes) > 1 and (
            len(_meshes) > MESH_CACHE_SIZE or sum(map(_nbytes, _meshes.values())) > MESH_CACHE_BYTES
        ):
            _meshes.popitem(last=False)
    return mesh


def _source_name(file: str) -> str:
    return "the data: URI" if file.startswith("data:") else f"asset file '{file}'"


def load_mesh_file(file: str, path: str, asset_dir: Path = ASSET_DIR, max_triangles: int | None = None) -> MeshData:
    """`read_mesh`, raising SceneError at JSON path `path`."""
    try:
        return read_mesh(file, asset_dir, max_triangles)
    except AssetError as e:
        raise _at(path, e) from None
