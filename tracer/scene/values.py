"""Value types of the scene format: numbers strict (no "1.5" strings, no booleans), finite and inside
float32's range, the renderer's; points, vectors, colours, pairs and faces; the small checks they are
made of, and errors raised at explicit locations."""

import math
from typing import Annotated, Any, TypeGuard, Union

from annotated_types import Ge, Gt, Le
from pydantic import AfterValidator, AllowInfNan, BeforeValidator, Strict, ValidationError
from pydantic_core import InitErrorDetails, PydanticCustomError

from tracer.errors import FINITE, FLOAT32, FLOAT32_MAX, show_value


def _error(message: str) -> PydanticCustomError:
    return PydanticCustomError("scene", "{message}", {"message": message})


def _raise_at(errors: list[tuple[tuple, str]]) -> None:
    """Raise errors at explicit locations relative to the model being validated."""
    if errors:
        details = [InitErrorDetails(type=_error(msg), loc=loc, input=None) for loc, msg in errors]
        raise ValidationError.from_exception_data("Scene", details)


def _is_number(v: Any) -> TypeGuard[int | float]:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _finite(v: float) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # an int too large for a float
        return False


def _float32(v: Any) -> Any:
    """Before-validator: a finite number past float32's range is an error (NaN, Infinity: the type's)."""
    if _is_number(v) and _finite(v) and abs(v) > FLOAT32_MAX:
        raise _error(FLOAT32)
    return v


def _triple(expected: str, scalar=None):
    """Before-validator: accept a list of three (and, with `scalar`, one number -> scalar(v))."""

    def check(v: Any) -> Any:
        if isinstance(v, list | tuple) and len(v) == 3:
            return v
        if scalar is not None and _is_number(v):
            if not _finite(v):
                raise _error(FINITE)
            return scalar(_float32(v))
        raise _error(f"expected {expected}, got {show_value(v)}")

    return check


def _grey(v: float) -> tuple[float, float, float]:
    if v < 0:
        raise _error("must be >= 0")
    f = float(v)
    return (f, f, f)


def _uniform_scale(v: float) -> tuple[float, float, float]:
    if v == 0:
        raise _error("must not be zero")
    f = float(v)
    return (f, f, f)


def _nonzero(v: float) -> float:
    if v == 0:
        raise _error("must not be zero")
    return v


def _nonzero_length(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if _length(v) == 0:
        raise _error("must not be a zero-length vector")
    return v


def _not_all_zero(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if not any(v):
        raise _error("must not be all zero: f_att = 1 / (c1 + c2 d + c3 d^2)")
    return v


def _pair(v: Any) -> Any:
    if isinstance(v, list | tuple) and len(v) == 2:
        return v
    raise _error(f"expected a pair [a, b], got {show_value(v)}")


# Numbers are finite and inside float32's range, the renderer's. The components of vectors and colours
# (F32, NonNeg) have that range as bounds of their own check (no Python call per vertex). A scalar field
# may add bounds (Field(gt=0, le=180)), which an annotation's bounds would override: its number (Num,
# Positive) checks the range in a before-validator instead.
F32 = Annotated[float, Strict(), AllowInfNan(False), Ge(-FLOAT32_MAX), Le(FLOAT32_MAX)]
NonNeg = Annotated[float, Strict(), AllowInfNan(False), Ge(0), Le(FLOAT32_MAX)]
Num = Annotated[float, Strict(), AllowInfNan(False), BeforeValidator(_float32)]
Positive = Annotated[float, Strict(), AllowInfNan(False), Gt(0), BeforeValidator(_float32)]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Str = Annotated[str, Strict()]
Vec3 = Annotated[tuple[F32, F32, F32], BeforeValidator(_triple("a point [x, y, z]"))]
Dir3 = Annotated[tuple[F32, F32, F32], BeforeValidator(_triple("a vector [x, y, z]")), AfterValidator(_nonzero_length)]
RGB = Annotated[
    tuple[NonNeg, NonNeg, NonNeg],
    BeforeValidator(
        _triple("an RGB triple [r, g, b] or a single number", _grey),
        json_schema_input_type=Union[NonNeg, tuple[NonNeg, NonNeg, NonNeg]],  # noqa: UP007
    ),
]
Attenuation = Annotated[
    tuple[NonNeg, NonNeg, NonNeg], BeforeValidator(_triple("[c1, c2, c3]")), AfterValidator(_not_all_zero)
]
NonZero = Annotated[F32, AfterValidator(_nonzero)]
Scale3 = Annotated[
    tuple[NonZero, NonZero, NonZero],
    BeforeValidator(
        _triple("a scale factor or [sx, sy, sz]", _uniform_scale),
        json_schema_input_type=Union[Num, tuple[Num, Num, Num]],  # noqa: UP007
    ),
]
Pair = Annotated[tuple[F32, F32], BeforeValidator(_pair)]
Face = Annotated[tuple[Int, Int, Int], BeforeValidator(_triple("a face [i, j, k] of three vertex indices"))]


def _length(v) -> float:
    return math.sqrt(sum(c * c for c in v))


def _sub(a, b) -> tuple[float, float, float]:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _parallel(a, b, eps: float = 1e-9) -> bool:
    """True when a and b are parallel (|a x b| tiny relative to |a| |b|)."""
    cross = (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
    return _length(cross) <= eps * _length(a) * _length(b)
