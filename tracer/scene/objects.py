"""The surfaces: spheres, planes, quads, disks, boxes, triangles and meshes (inline or from a file), each
with a material, a name for the ray tree and a velocity; and the primitives the renderer will build."""

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, ValidationInfo, field_validator

from tracer.scene.base import _has, _Model
from tracer.scene.context import MeshFile
from tracer.scene.materials import MaterialRef, _unknown_material
from tracer.scene.values import Bool, Dir3, Face, Num, Scale3, Str, Vec3, _error, _parallel, _sub, _triple


class Transform(_Model):
    """Applied scale, then rotate (about X, then Y, then Z), then translate."""

    translate: Vec3 = Field((0.0, 0.0, 0.0), description="Translation (world units).")
    rotate: Vec3 = Field((0.0, 0.0, 0.0), description="Rotations about X, Y, Z (degrees).")
    scale: Scale3 = Field((1.0, 1.0, 1.0), description="Scale factor, or [sx, sy, sz]; non-zero.")


class _Object(_Model):
    type: str = Field(description="Object type.")
    material: MaterialRef = Field(description="A material name from 'materials', or an inline material.")
    name: Str | None = Field(None, description="Name shown in the ray tree.")
    velocity: Vec3 = Field(
        (0.0, 0.0, 0.0),
        description="World units per unit time; at ray time T the object is at p + velocity T.",
    )

    @field_validator("material")
    @classmethod
    def _known_material(cls, v: Any, info: ValidationInfo) -> Any:
        names = (info.context or {}).get("material_names")
        if isinstance(v, str) and names is not None and v not in names:
            raise _error(_unknown_material(v, names))
        return v


class Sphere(_Object):
    """Sphere; geometric normal outwards."""

    type: Literal["sphere"] = Field(description="Object type.")
    center: Vec3 = Field(description="Centre (world units).")
    radius: Num = Field(gt=0, description="Radius (world units).")


class Plane(_Object):
    """Infinite two-sided plane."""

    type: Literal["plane"] = Field(description="Object type.")
    point: Vec3 = Field(description="A point on the plane (world units).")
    normal: Dir3 = Field(description="Geometric normal.")


class Quad(_Object):
    """Parallelogram corner + s edge1 + t edge2, s, t in [0, 1]; normal normalize(edge1 x edge2)."""

    type: Literal["quad"] = Field(description="Object type.")
    corner: Vec3 = Field(description="One corner (world units).")
    edge1: Dir3 = Field(description="First edge from the corner (world units).")
    edge2: Dir3 = Field(description="Second edge from the corner (world units).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if _has(v, "edge1", "edge2") and _parallel(v.edge1, v.edge2):
            return [(("edge2",), "must not be parallel to edge1 (degenerate quad)")]
        return []


class Disk(_Object):
    """Flat disk, two-sided."""

    type: Literal["disk"] = Field(description="Object type.")
    center: Vec3 = Field(description="Centre (world units).")
    normal: Dir3 = Field(description="Geometric normal.")
    radius: Num = Field(gt=0, description="Radius (world units).")


class Box(_Object):
    """Axis-aligned box [min, max], optionally transformed; normals outwards."""

    type: Literal["box"] = Field(description="Object type.")
    min: Vec3 = Field(description="Minimum corner (world units, before the transform).")
    max: Vec3 = Field(description="Maximum corner (world units, before the transform).")
    transform: Transform | None = Field(None, description="Scale, rotate, translate applied to the box.")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if not _has(v, "min", "max"):
            return []
        return [
            (("max", axis), f"must be greater than min[{axis}] = {v.min[axis]:g}")
            for axis in range(3)
            if v.max[axis] <= v.min[axis]
        ]


class Triangle(_Object):
    """One triangle; geometric normal normalize((v1 - v0) x (v2 - v0))."""

    type: Literal["triangle"] = Field(description="Object type.")
    vertices: Annotated[
        tuple[Vec3, Vec3, Vec3], BeforeValidator(_triple("three vertices [[x, y, z], [x, y, z], [x, y, z]]"))
    ] = Field(description="The three vertices v0, v1, v2 (world units).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        if _has(v, "vertices"):
            v0, v1, v2 = v.vertices
            if _parallel(_sub(v1, v0), _sub(v2, v0)):
                return [(("vertices",), "the three vertices are collinear (degenerate triangle)")]
        return []


class Mesh(_Object):
    """Triangle mesh: inline vertices + faces, or a file (OBJ/PLY/glTF) from the asset folder."""

    type: Literal["mesh"] = Field(description="Object type.")
    vertices: list[Vec3] | None = Field(None, min_length=1, description="Inline vertex positions (world units).")
    faces: list[Face] | None = Field(
        None,
        min_length=1,
        description="Inline triangles as vertex indices [i, j, k] (0-based, counter-clockwise).",
    )
    file: MeshFile | None = Field(None, description="Mesh file in the asset folder, or a data: URI.")
    transform: Transform | None = Field(None, description="Scale, rotate, translate applied to the mesh.")
    smooth: Bool = Field(False, description="Interpolate vertex normals (smooth shading).")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        def given(field: str) -> bool:  # set to something other than null (valid or not)
            return field in v.model_fields_set and (not _has(v, field) or getattr(v, field) is not None)

        errors = []
        if given("file"):
            if given("vertices") or given("faces"):
                errors.append((("file",), "give either 'file' or inline 'vertices' + 'faces', not both"))
        else:
            for field in ("vertices", "faces"):
                if not given(field):
                    errors.append(((field,), f"required field '{field}' is missing (or give a 'file')"))
        if _has(v, "vertices", "faces") and v.vertices is not None and v.faces is not None:
            n, bad = len(v.vertices), []
            for k, face in enumerate(v.faces):
                bad += [(k, j, i) for j, i in enumerate(face) if not 0 <= i < n]
            for k, j, i in bad[:10]:
                errors.append((("faces", k, j), f"vertex index {i} is out of range (the mesh has {n} vertices)"))
            if len(bad) > 10:
                errors.append((("faces",), f"{len(bad) - 10} more vertex indices are out of range"))
        return errors


Object = Annotated[Sphere | Plane | Quad | Disk | Box | Triangle | Mesh, Field(discriminator="type")]


def primitive_count(objects: list) -> int:
    """Primitives the renderer will build: a box is 12 triangles, an inline mesh its faces.

    Meshes from files are not counted here (their size is known when the file is read)."""
    return sum(len(o.faces or ()) if isinstance(o, Mesh) else 12 if isinstance(o, Box) else 1 for o in objects)
