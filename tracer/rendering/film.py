"""The film: exposure, sRGB encoding, PNG and EXR files (its reconstruction filters: tracer/kernels/filters.py).

PNG = sRGB OETF of clamp(2^exposure L, 0, 1) (docs/scene-format.md, "Film"); the EXR keeps the linear
radiance without exposure, as 32-bit floats.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# ------------------------------------------------------------------------------------ output


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB OETF (IEC 61966-2-1) of values in [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def to_srgb8(image: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """(H, W, 3) linear radiance -> (H, W, 3) uint8 sRGB."""
    scaled = np.nan_to_num(image, nan=0.0, posinf=1.0, neginf=0.0) * (2.0**exposure)
    return np.round(srgb_encode(scaled) * 255.0).astype(np.uint8)


def write_png(path: str | Path, image: np.ndarray, exposure: float = 0.0) -> None:
    from PIL import Image

    Image.fromarray(to_srgb8(image, exposure), "RGB").save(str(path))


def png_bytes(image: np.ndarray, exposure: float = 0.0, *, srgb: bool = True) -> bytes:
    """An 8-bit PNG: (H, W, 3) linear radiance through the sRGB curve; with `srgb=False`, values in
    [0, 1] written as they are (data such as a normal map 0.5 + 0.5 n), (H, W) as grey."""
    import io

    from PIL import Image

    if srgb:
        picture = Image.fromarray(to_srgb8(image, exposure), "RGB")
    else:
        scaled = np.nan_to_num(image) * (2.0**exposure)
        picture = Image.fromarray(np.round(np.clip(scaled, 0.0, 1.0) * 255.0).astype(np.uint8))
    buf = io.BytesIO()
    picture.save(buf, format="PNG")
    return buf.getvalue()


def write_exr(path: str | Path, image: np.ndarray, layers: dict[str, np.ndarray] | None = None) -> None:
    """Linear float32 RGB (and optional extra single- or 3-channel layers) as OpenEXR."""
    import OpenEXR

    channels = {"RGB": np.ascontiguousarray(image, dtype=np.float32)}
    for name, arr in (layers or {}).items():
        channels[name] = np.ascontiguousarray(arr, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


def read_exr(path: str | Path) -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        ch = f.channels()
        if "RGB" in ch:
            return np.asarray(ch["RGB"].pixels, dtype=np.float32)
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)


def aov_layers(aovs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """AOVs as EXR layers: depth.Z and rays.Y (one channel); normal, albedo, variance (.R .G .B)."""
    names = {"depth": "depth.Z", "rays": "rays.Y"}
    return {names.get(k, k): v for k, v in aovs.items()}


def heat_map(values: np.ndarray) -> np.ndarray:
    """A (H, W) map of non-negative values as a linear-RGB image from black through red to yellow
    to white (for the rays-per-pixel AOV): 0 is black, the maximum white."""
    v = values / max(float(values.max()), 1e-12)
    r = np.clip(3 * v, 0, 1)
    g = np.clip(3 * v - 1, 0, 1)
    b = np.clip(3 * v - 2, 0, 1)
    return (np.stack([r, g, b], axis=-1) ** 2.2).astype(np.float32)
