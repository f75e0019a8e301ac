"""The base of every scene model (`_Model`): unknown keys are errors, and every independent error is
reported at once: the checks between fields (`_checks`) run on the valid model, and also when some
fields failed, on the fields that are valid (`_Partial`)."""

import functools
from collections.abc import Mapping
from typing import Annotated, Any, get_args

from pydantic import BaseModel, ConfigDict, TypeAdapter, ValidationError, ValidationInfo, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError
from pydantic_core.core_schema import ErrorType

from tracer.scene.values import _error, _raise_at

_KNOWN_ERRORS = frozenset(get_args(ErrorType))


def _details(err: Mapping[str, Any]) -> InitErrorDetails:
    """A pydantic error as raised (ValidationError.errors()) -> the same error, to raise again."""
    ctx = err.get("ctx")
    if err["type"] in _KNOWN_ERRORS:
        detail = InitErrorDetails(type=err["type"], loc=err["loc"], input=err.get("input"))
        if ctx is not None:
            detail["ctx"] = ctx
        return detail
    custom = PydanticCustomError(err["type"], "{message}", {**(ctx or {}), "message": err["msg"]})
    return InitErrorDetails(type=custom, loc=err["loc"], input=err.get("input"))


@functools.cache
def _field_adapter(model: type[BaseModel], name: str) -> TypeAdapter:
    field = model.model_fields[name]
    # a type form made at run time from the field, which pyright cannot read statically
    return TypeAdapter(Annotated[field.annotation, field])  # pyright: ignore[reportArgumentType, reportInvalidTypeForm]


class _Partial:
    """The valid fields of a model input whose validation failed: each field is validated alone on
    first use; a field that failed (or is missing) is not there at all, so `_has` says False."""

    def __init__(self, model: type[BaseModel], data: dict, failed: set, context: Any):
        self._model, self._data, self._failed, self._context = model, data, failed, context
        self.model_fields_set = {k for k in data if k in model.model_fields}

    def __getattr__(self, name: str) -> Any:
        field = self._model.model_fields.get(name)
        if field is None or name in self._failed:
            raise AttributeError(name)
        if name in self._data:
            try:
                value = _field_adapter(self._model, name).validate_python(self._data[name], context=self._context)
            except ValidationError:
                raise AttributeError(name) from None
        elif field.is_required():
            raise AttributeError(name)
        else:
            value = field.get_default(call_default_factory=True)
        setattr(self, name, value)
        return value


def _has(v: Any, *names: str) -> bool:
    """True when the fields `names` of a model (or a _Partial) are valid, so a check may read them."""
    return all(hasattr(v, n) for n in names)


class _Model(BaseModel):
    """Base of every scene model: unknown keys are errors, and every independent error is reported.

    Checks between fields (`_checks`) run on the valid model, and also when some fields failed: then
    on the fields that are valid (`_Partial`), so fixing one error never reveals another that was
    there all along. A check reads only what `_has` says is valid."""

    model_config = ConfigDict(extra="forbid")

    @classmethod
    def _checks(cls, v: Any, info: ValidationInfo) -> list[tuple[tuple, str]]:
        """(location relative to the model, message) of each failed check between fields."""
        return []

    @model_validator(mode="wrap")
    @classmethod
    def _every_error(cls, data: Any, handler, info: ValidationInfo) -> Any:
        if cls._checks.__func__ is _Model._checks.__func__:
            return handler(data)
        try:
            model = handler(data)
        except ValidationError as exc:
            if not isinstance(data, dict):
                raise
            errors = exc.errors()
            failed = {e["loc"][0] for e in errors if e["loc"]}
            found = cls._checks(_Partial(cls, data, failed, info.context), info)
            if not found:
                raise
            extra = [InitErrorDetails(type=_error(msg), loc=loc, input=None) for loc, msg in found]
            raise ValidationError.from_exception_data(cls.__name__, [*map(_details, errors), *extra]) from None
        _raise_at(cls._checks(model, info))
        return model
