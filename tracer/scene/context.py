"""What reaches the validators through pydantic's validation context: the limits (tracer/limits.py) and,
when validation is asked to resolve them (`load_scene(..., assets=DIR)`), the asset folder: its files
are checked and read as part of validation (an image's header only), their errors at their own paths.
"""

from pathlib import Path
from typing import Annotated

from pydantic import AfterValidator, ValidationInfo

from tracer.assets import AssetError, image_size, path_problem, read_mesh
from tracer.limits import Limits
from tracer.scene.values import Str, _error


def _limits(info: ValidationInfo) -> Limits:
    return (info.context or {}).get("limits") or Limits()


def _asset_dir(info: ValidationInfo) -> Path | None:
    """The asset folder to resolve files in, when validation is asked to (`load_scene(..., assets=DIR)`)."""
    return (info.context or {}).get("assets")


def _asset_file(v: str) -> str:
    """A file never reaches outside the asset folder (existence is checked by `resolve_asset`)."""
    problem = path_problem(v)
    if problem:
        raise _error(problem)
    return v


def _image_size(file: str, info: ValidationInfo) -> tuple[int, int]:
    """(width, height) of an image from its header, read once per validation (the scene's total reads it again)."""
    asset_dir = _asset_dir(info)
    assert info.context is not None and asset_dir is not None, "called when validation resolves assets alone"
    sizes = info.context.setdefault("image_sizes", {})
    if file not in sizes:
        try:
            sizes[file] = image_size(file, asset_dir)
        except AssetError as e:
            sizes[file] = e
    if isinstance(sizes[file], AssetError):
        raise sizes[file]
    return sizes[file]


def _image_file(v: str, info: ValidationInfo) -> str:
    """With an asset folder: the image exists (or is a data: URI) and its header is readable; no pixels decoded."""
    if _asset_dir(info) is not None:
        try:
            width, height = _image_size(v, info)
        except AssetError as e:
            raise _error(e.message) from None
        problem = texture_problem(width, height, 0, _limits(info))
        if problem:
            raise _error(problem)
    return v


def texture_problem(width: int, height: int, used: int, limits: Limits) -> str | None:
    """What is wrong with one more image of width x height pixels when the scene's images before it hold
    `used` pixels (None: nothing). Validation and the renderer both ask, before any pixel is decoded."""
    pixels = width * height
    if pixels > limits.max_texture_pixels:
        return f"the image is {width}x{height} = {pixels} pixels; {limits.at_most('max_texture_pixels')}"
    if used + pixels > limits.max_texture_pixels_total:
        return (
            f"with this {width}x{height} image the scene's images come to {used + pixels} pixels; all of a "
            f"scene's images together {limits.at_most('max_texture_pixels_total')}"
        )
    return None


def _mesh_file(v: str, info: ValidationInfo) -> str:
    """With an asset folder: the mesh exists (or is a data: URI) and reads as triangles, no more of them than
    the scene may have primitives (a glTF's counted from its node tree before any is built)."""
    folder = _asset_dir(info)
    if folder is not None:
        try:
            read_mesh(v, folder, _limits(info).max_primitives)
        except AssetError as e:
            raise _error(e.message) from None
    return v


AssetFile = Annotated[Str, AfterValidator(_asset_file)]
ImageFile = Annotated[AssetFile, AfterValidator(_image_file)]
MeshFile = Annotated[AssetFile, AfterValidator(_mesh_file)]
