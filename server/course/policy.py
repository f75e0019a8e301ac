"""An assignment's policy, as published beside its grading spec: the deadline and a late cut-off with its
penalty, the submission limit, which submission counts, the starter scene, whether the reference image is
shown, and when each test's feedback is shown. Validated like a scene: each error at its JSON path."""

from __future__ import annotations

from datetime import UTC, datetime
from enum import StrEnum
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, model_validator

ISO_EXAMPLE = "2026-12-01T23:59:00Z or 2026-12-01T23:59:00+01:00"


def _instant(v: Any) -> Any:
    """ISO 8601 text with a zone -> an aware datetime in UTC (a time without a zone is ambiguous: refused)."""
    if isinstance(v, datetime):
        when = v
    elif isinstance(v, str):
        try:
            when = datetime.fromisoformat(v.strip())
        except ValueError:
            raise ValueError(f"expected an ISO 8601 time with a zone, such as {ISO_EXAMPLE}; got {v[:60]!r}") from None
    else:
        raise ValueError(f"expected an ISO 8601 time with a zone as text, such as {ISO_EXAMPLE}")
    if when.tzinfo is None or when.utcoffset() is None:
        raise ValueError(f"{str(v)[:60]!r} has no zone: add one, such as {ISO_EXAMPLE}")
    return when.astimezone(UTC)


Instant = Annotated[datetime, BeforeValidator(_instant)]


class When(StrEnum):
    """When a test's feedback (or the score) is shown to the student."""

    now = "now"  # as soon as it is graded
    after_deadline = "after_deadline"  # once the student can no longer submit (their late cut-off, else deadline)
    never = "never"  # only the instructor sees it


ORDER = {When.now: 0, When.after_deadline: 1, When.never: 2}


class Feedback(BaseModel):
    model_config = ConfigDict(extra="forbid")

    default: When = Field(When.now, description="when a test's feedback is shown, unless `tests` names it")
    tests: dict[str, When] = Field(
        default_factory=dict,
        description="by test: 'validity', a requirement's name, or an image test: 'flip', 'ssim', 'psnr', 'pixels'",
    )
    score: When | None = Field(
        None, description="when the score is shown; default: the latest of the tests' (it would tell their sum)"
    )

    def score_when(self) -> When:
        if self.score is not None:
            return self.score
        return max([self.default, *self.tests.values()], key=ORDER.__getitem__)


class Policy(BaseModel):
    model_config = ConfigDict(extra="forbid")

    deadline: Instant = Field(description="ISO 8601 with a zone")
    late_until: Instant | None = Field(None, description="late submissions are taken until then (ISO 8601)")
    late_penalty: float = Field(0.0, ge=0, le=1, description="fraction of a late submission's points taken off")
    max_submissions: int | None = Field(
        None, ge=1, le=10_000, description="attempts per student; an invalid or ungradable submission costs none"
    )
    counts: Literal["last", "best"] = Field("last", description="which graded submission is the grade")
    starter: dict[str, Any] | None = Field(None, description="a scene the students start from")
    show_reference: bool = Field(False, description="whether students see the reference image")
    feedback: Feedback = Field(default_factory=Feedback)
    open: bool = Field(False, description="anyone with the assignment's link may join by a name")

    @model_validator(mode="after")
    def _late(self) -> Policy:
        if self.late_until is not None and self.late_until < self.deadline:
            raise ValueError("late_until must not be before the deadline")
        return self

    def stored(self) -> dict:
        return self.model_dump(mode="json")


class AssignmentIn(Policy):
    """POST /api/assignments (and PUT, an edit): the grading spec and the policy."""

    spec: dict[str, Any] = Field(description="the grading spec (docs/grading.md), its reference scene inline")
    reference: dict[str, Any] | None = Field(
        None, description="the reference scene, when the spec names it as a file (scenes/grading/assignment.json)"
    )
