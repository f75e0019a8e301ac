"""A job's files: what each one is, by name, in its folder DATA/jobs/<id>/ (the store reads and writes them)."""

from __future__ import annotations

from enum import StrEnum


class JobFile(StrEnum):
    """A job's files, in its folder DATA/jobs/<id>/ (the value is the file's name). Each is written
    whole (a temporary file renamed over the old one): a reader sees the old file or the new one."""

    image_png = "image.png"  # the latest image, 8-bit sRGB with the film's exposure (previews, then the final)
    image_exr = "image.exr"  # the same pass as linear float32 radiance
    aov_rays = "aov_rays.png"  # the AOV pictures of a finished job (server/queue/outputs.py, aov_pictures)
    aov_depth = "aov_depth.png"
    aov_normal = "aov_normal.png"
    aov_albedo = "aov_albedo.png"
    aov_variance = "aov_variance.png"
    aov_ranges = "aovs.json"  # {name: [min, max]} of the values each AOV picture shows
    aov_floats = "aovs.exr"  # the float AOVs: the variance as RGB (what the grader reads), the others as layers
    radiosity = "radiosity.json"  # a finished radiosity job's solution
    snapshot = "snapshot.npz"  # the film after pass `snapshot` (a try that takes the job continues from it)
    raytree = "raytree.json"  # a ray-tree job's answer

    @classmethod
    def image(cls, fmt: str) -> JobFile:
        """The latest image as "png" or "exr"."""
        return cls(f"image.{fmt}")

    @classmethod
    def aov(cls, name: str) -> JobFile:
        """The AOV picture `name` (one of AOV_NAMES; ValueError for any other)."""
        return cls(f"aov_{name}.png")


AOV_NAMES = tuple(f.removeprefix("aov_").removesuffix(".png") for f in JobFile if f.startswith("aov_"))
