"""What a student hands in (a scene, or an image of their own), the student's id made from a file name,
and their image files read: PNG at its own bit depth, EXR as linear radiance."""

from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass

import numpy as np

from tracer.grading import metrics

IMAGE_KINDS = ("png", "exr")  # the submissions that are images (the others are scenes)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"  # a PNG's first bytes
EXR_MAGIC = b"v/1\x01"  # an OpenEXR file's
ALLOWED = "a submitted image is a PNG or an OpenEXR file"


@dataclass
class Submission:
    """What a student handed in: a scene (JSON bytes) or an image (PNG or EXR bytes)."""

    student: str
    data: bytes
    kind: str = "scene"  # scene | png | exr
    filename: str = ""


STUDENT_NAME_CHARS = 80  # the longest student id, in characters
STUDENT_NAME_BYTES = 240  # ... and in UTF-8 bytes (it names a folder: file systems allow 255)


def student_name(text: str) -> str:
    """A file or folder name -> a safe student id: Unicode letters, marks and digits (NFC, so a name from
    a macOS zip matches the same name typed elsewhere), '.', '_' and '-'; every other run of characters
    becomes one '_', and leading or trailing '.' and '_' go ("Zoë O'Brien" -> "Zoë_O_Brien"). The page
    asks the server for this (POST /api/grade/students) rather than keeping a copy of the rule."""
    text = unicodedata.normalize("NFC", text)
    kept = "".join(c if c in "._-" or unicodedata.category(c)[0] in "LMN" else "\0" for c in text)
    name = re.sub("\0+", "_", kept).strip("._") or "student"
    name = name[:STUDENT_NAME_CHARS]
    while len(name.encode("utf-8")) > STUDENT_NAME_BYTES:
        name = name[:-1]
    return name.rstrip("._") or "student"


def read_image(data: bytes, kind: str) -> np.ndarray:
    """A PNG (8 or 16 bit; grey, RGB or RGBA) as displayed floats in [0, 1], or an EXR as linear floats."""
    return decode_image(data, kind)[0]


def decode_image(data: bytes, kind: str) -> tuple[np.ndarray, metrics.Encoding]:
    """A student's image file -> (H, W, 3) float32 pixels and how they are encoded:
    - an EXR holds linear radiance without exposure (as `render --exr` writes it): R, G, B (or Y, grey)
      channels, 32-bit float or 16-bit half float; NaN and infinities become 0;
    - a PNG holds sRGB(clamp(2^exposure L)) in [0, 1], at its own bit depth (16-bit PNGs keep their
      16 bits; Pillow would round them to 8), grey, grey with alpha, RGB, RGBA or a palette; alpha is dropped.
    Raises GradingError for a file that is not what its kind says, told by its first bytes before any
    decoder sees it (Pillow would read dozens of formats, EPS through Ghostscript)."""
    magic, name = (EXR_MAGIC, "an OpenEXR file") if kind == "exr" else (PNG_MAGIC, "a PNG file")
    if not data.startswith(magic):
        from tracer.assets import other_format

        raise metrics.GradingError(f"cannot read the {kind.upper()} image: it is "
                                   f"{other_format(data[:16]) or 'not ' + name}; {ALLOWED}")  # fmt: skip
    if kind == "exr":
        return _decode_exr(data)
    bits = _png_bit_depth(data)
    if bits == 16:
        return _decode_png16(data)
    import io

    from PIL import Image, UnidentifiedImageError

    try:
        im = Image.open(io.BytesIO(data), formats=["PNG"])
        im.load()
    except (UnidentifiedImageError, OSError, ValueError) as e:
        raise metrics.GradingError(f"cannot read the PNG image: {e}") from None
    a = np.asarray(im.convert("RGBA" if "A" in im.mode or "transparency" in im.info else "RGB"), dtype=np.float64)
    return np.clip(a[..., :3] / 255.0, 0.0, 1.0).astype(np.float32), metrics.Encoding("png", bits or 8)


def _png_bit_depth(data: bytes) -> int | None:
    """The bits per sample of a PNG's pixel values, from its header (a palette's entries have 8); None: not a PNG."""
    if len(data) < 26 or data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR":
        return None
    depth, colour = data[24], data[25]
    return 8 if colour == 3 else depth  # 3: a palette of 8-bit RGB entries


def _decode_png16(data: bytes) -> tuple[np.ndarray, metrics.Encoding]:
    import png  # pypng: Pillow has no 16-bit colour modes (it reads a 48-bit PNG as 24-bit)

    try:
        width, height, rows, info = png.Reader(bytes=data).asDirect()
        a = np.vstack([np.asarray(r, dtype=np.float64) for r in rows]).reshape(height, width, info["planes"])
    except (png.Error, ValueError, EOFError) as e:
        raise metrics.GradingError(f"cannot read the PNG image: {e}") from None
    bits = info["bitdepth"]  # 16, or fewer where an sBIT chunk says so
    a = a / float(2**bits - 1)
    a = a[..., :1] if info["greyscale"] else a[..., :3]  # alpha dropped
    return np.clip(np.broadcast_to(a, (height, width, 3)), 0.0, 1.0).astype(np.float32), metrics.Encoding("png", bits)


def _decode_exr(data: bytes) -> tuple[np.ndarray, metrics.Encoding]:
    import tempfile

    import OpenEXR

    with tempfile.NamedTemporaryFile(suffix=".exr") as f:
        f.write(data)
        f.flush()
        try:
            with OpenEXR.File(f.name, separate_channels=True) as exr:
                channels = {name: np.asarray(c.pixels) for name, c in exr.channels().items()}
        except Exception:  # OpenEXR raises plain exceptions for broken files
            raise metrics.GradingError("cannot read the EXR image: it is not an OpenEXR file") from None
    names = ["R", "G", "B"] if {"R", "G", "B"} <= set(channels) else ["Y"] * 3 if "Y" in channels else None
    if names is None:
        found = ", ".join(sorted(channels)) or "none"
        raise metrics.GradingError(f"the EXR image has no colour: R, G and B (or Y) channels wanted; it has {found}")
    if any(channels[n].dtype.kind != "f" for n in names):
        raise metrics.GradingError("the EXR image holds integers; radiance is wanted as half or full floats")
    bits = 16 if any(channels[n].dtype == np.float16 for n in names) else 32
    image = np.stack([channels[n].astype(np.float32) for n in names], axis=-1)
    return np.nan_to_num(image, nan=0.0, posinf=0.0, neginf=0.0), metrics.Encoding("exr", bits)
