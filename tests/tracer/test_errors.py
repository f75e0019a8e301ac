"""The one translation of pydantic's errors into {path, message} (tracer/errors.py), on models of its
own; the scene format's and the assignment spec's messages are tested in test_scene.py and
test_grading.py, the API's in test_api_errors.py."""

from typing import Annotated, Literal

import pytest
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from tracer.errors import FLOAT32, FLOAT32_MAX, SceneError, json_path, pydantic_errors, show_value, translate_error


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Circle(_Strict):
    type: Literal["circle"]
    radius: float = Field(gt=0)


class Square(_Strict):
    type: Literal["square"]
    side: float = Field(ge=0, le=FLOAT32_MAX)


class Drawing(_Strict):
    name: str
    shapes: list[Annotated[Circle | Square, Field(discriminator="type")]] = []
    colours: dict[str, tuple[float, float, float]] = {}
    source: str | dict = "inline"
    mode: Literal["fill", "stroke"] | None = None

    @field_validator("name")
    @classmethod
    def _not_blank(cls, v: str) -> str:
        if not v.strip():
            raise ValueError("must not be blank")
        return v


def errors(data: dict, root=Drawing) -> list[dict]:
    with pytest.raises(ValidationError) as e:
        Drawing.model_validate(data)
    return pydantic_errors(e.value, root)


def test_errors_each_at_its_json_path_with_a_message_to_act_on():
    got = errors(
        {
            "name": " ",
            "shapes": [{"type": "circle", "radius": -1}, {"type": "sqaure"}, {"side": 1}],
            "colours": {"dark red": [1, 2]},
            "mode": "fil",
            "colour": 1,
        }
    )
    assert got == [
        {"path": "name", "message": "must not be blank"},
        {"path": "shapes[0].radius", "message": "must be > 0"},
        {"path": "shapes[1].type", "message": "unknown shape type 'sqaure'; expected one of: circle, square; "
                                              "did you mean 'square'?"},
        {"path": "shapes[2].type", "message": "required field 'type' is missing (one of: circle, square)"},
        {"path": 'colours["dark red"][2]', "message": "missing: the list needs 3 items or more"},
        {"path": "mode", "message": "expected one of: fill, stroke; got \"fil\"; did you mean 'fill'?"},
        {"path": "colour", "message": "unknown field 'colour'; did you mean 'colours'?"},
    ]  # fmt: skip


def test_errors_drop_the_member_names_of_plain_unions_and_say_each_once():
    got = errors({"name": "x", "source": 5})
    assert got == [
        {"path": "source", "message": "expected a string, got 5"},
        {"path": "source", "message": "expected a JSON object {...}, got 5"},
    ]
    assert errors({"name": "x", "source": 5}) == pydantic_errors(errors_raw({"name": "x", "source": 5}) * 2, Drawing)


def errors_raw(data: dict) -> list[dict]:
    try:
        Drawing.model_validate(data)
    except ValidationError as e:
        return e.errors()
    raise AssertionError("valid")


def test_errors_float32_range_and_missing_fields():
    got = errors({"shapes": [{"type": "square", "side": 1e39}]})
    assert got == [
        {"path": "name", "message": "required field 'name' is missing"},
        {"path": "shapes[0].side", "message": FLOAT32},
    ]


def test_errors_without_a_root_keep_the_location():
    """A request's body (the API strips "body" first) or any other model, as far as the loc tells."""
    [err] = errors_raw({"name": "x", "colour": 1})
    assert translate_error(err) == {"path": "colour", "message": "unknown field 'colour'"}
    assert translate_error({**err, "loc": ("items", 2, "function-after[check(), str]", "colour")})["path"] == (
        "items[2].colour"
    )


def test_errors_paths_values_and_scene_errors():
    assert json_path(("materials", "dark red", "kd", 1)) == 'materials["dark red"].kd[1]'
    assert json_path(()) == ""
    assert show_value(float("nan")) == "NaN" and show_value("x" * 100) == '"' + "x" * 36 + "..."
    e = SceneError([{"path": "a.b", "message": "bad"}, {"path": "", "message": "worse"}])
    assert str(e) == "a.b: bad\nworse"
    assert e.errors[1]["message"] == "worse"
