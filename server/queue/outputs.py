"""The files a finished render try writes besides its image (server/queue/render_try.py): the AOV pictures
with their ranges, and EXR bytes."""

from __future__ import annotations


def aov_pictures(aovs: dict) -> tuple[dict[str, bytes], dict[str, list[float]]]:
    """The renderer's AOVs as PNGs for the page, and each one's [min, max] (the legend of its colours).

    rays: rays traced per pixel as a heat map (black 0 ... red ... yellow ... white the maximum);
    depth: distance to the eye ray's hit as grey, near white to far dark grey, black where nothing was hit;
    normal: the shading normal as 0.5 + 0.5 n (no sRGB curve: the bytes are the vector);
    albedo: kd after texturing (sRGB like the image); variance: the mean of the RGB variance as a heat map."""
    import numpy as np

    from tracer.rendering.film import heat_map, png_bytes

    out: dict[str, bytes] = {}
    ranges: dict[str, list[float]] = {}

    def span(name: str, values: np.ndarray) -> None:
        finite = values[np.isfinite(values)]
        ranges[name] = [float(finite.min()), float(finite.max())] if finite.size else [0.0, 0.0]

    if "rays" in aovs:
        rays = np.nan_to_num(aovs["rays"])
        span("rays", rays)
        out["rays"] = png_bytes(heat_map(rays))
    if "depth" in aovs:
        depth = np.nan_to_num(aovs["depth"], posinf=0.0)
        hit = depth > 0
        far = float(depth.max()) if hit.any() else 1.0
        span("depth", depth[hit] if hit.any() else depth)
        out["depth"] = png_bytes(np.where(hit, 1.0 - 0.85 * depth / far, 0.0), srgb=False)
    if "normal" in aovs:
        normal = np.nan_to_num(aovs["normal"])
        span("normal", normal)
        out["normal"] = png_bytes(0.5 + 0.5 * normal, srgb=False)
    if "albedo" in aovs:
        albedo = np.nan_to_num(aovs["albedo"])
        span("albedo", albedo)
        out["albedo"] = png_bytes(albedo)
    if "variance" in aovs:
        variance = np.nan_to_num(aovs["variance"]).mean(axis=-1)
        span("variance", variance)
        out["variance"] = png_bytes(heat_map(variance))
    return out, ranges


def exr_bytes(image, layers: dict | None = None) -> bytes:
    """An EXR file's bytes (tracer.rendering.film.write_exr writes files: through a temporary one)."""
    import tempfile
    from pathlib import Path

    from tracer.rendering.film import write_exr

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "image.exr"
        write_exr(path, image, layers)
        return path.read_bytes()
