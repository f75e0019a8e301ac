"""An assignment's policy, as published beside its grading spec: the deadline and a late cut-off with its
penalty, the submission limit, which submission counts, the starter scene, whether the reference image is
shown, and when each test's feedback is shown. Validated like a scene: each error at its JSON path.

**What a student sees at a moment** (`feedback_view`): the one place the feedback policy is applied to a graded
report, for a student's submission (server/course/service.py) and for the publish form's preview of an example
(POST /api/assignments/preview-feedback, `preview`), so that the preview cannot drift from what students get. A
hidden image test hides the error map, the rejected pixels and the metrics (they would tell it), and the ray trees
at a pixel; a shown image test's "Where to look" then names no picture (`where_without_pictures`), and `withheld`
says what is hidden and when it appears."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from tracer.grading.imagetests import where_without_pictures

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

    default: When = Field(default=When.now, description="when a test's feedback is shown, unless `tests` names it")
    tests: dict[str, When] = Field(
        default_factory=dict,
        description="by test: 'validity', a requirement's name, or an image test: 'flip', 'ssim', 'psnr', 'pixels'",
    )
    score: When | None = Field(
        default=None, description="when the score is shown; default: the latest of the tests' (it would tell their sum)"
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
    regrade_deadline: Instant | None = Field(
        None, description="regrade requests are taken until then (ISO 8601); none: a week after the student's late"
        " cut-off (server/course/regrade.py)",
    )  # fmt: skip
    max_submissions: int | None = Field(
        None, ge=1, le=10_000, description="attempts per student; an invalid or ungradable submission costs none"
    )
    counts: Literal["last", "best"] = Field("last", description="which graded submission is the grade")
    starter: dict[str, Any] | None = Field(None, description="a scene the students start from")
    show_reference: bool = Field(False, description="whether students see the reference image")
    feedback: Feedback = Field(default_factory=Feedback)
    open: bool = Field(False, description="anyone with the assignment's link may join by a name")

    @field_validator("regrade_deadline")
    @classmethod
    def _regrade(cls, v: datetime | None, info: ValidationInfo) -> datetime | None:
        deadline = info.data.get("deadline")
        if v is not None and deadline is not None and v < deadline:
            raise ValueError("the regrade deadline must not be before the deadline")
        return v

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


# -- what a student sees at a moment ---------------------------------------------------------------------------

IMAGE_TESTS = ("flip", "ssim", "psnr", "pixels")
MAP_PICTURES = ("error_map.png", "rejected.png")  # shown only when every image test's feedback is


def iso(t: float | None) -> str | None:
    return None if t is None else datetime.fromtimestamp(t, UTC).isoformat().replace("+00:00", "Z")


@dataclass(frozen=True)
class Moment:
    """Who looks, and when (Unix times): the instructor sees everything; a student a test shown `now` at once,
    one shown `after_deadline` once `now` reaches `cut` (their late cut-off, else their deadline: an extension
    moves it), one shown `never` not at all."""

    now: float
    cut: float
    instructor: bool = False

    def shows(self, when: str) -> bool:
        if self.instructor or when == When.now:
            return True
        if when == When.never:
            return False
        return self.now >= self.cut


def when_of(feedback: Feedback, key: str) -> When:
    return When(feedback.tests.get(key, feedback.default))


def map_shown(feedback: Feedback, image_tests: Iterable[str], m: Moment) -> bool:
    """Whether the error map and the rejected pixels (and the metrics, the ray trees at a pixel, the probes) are
    shown: every image test's feedback shown (they would tell a hidden one's result)."""
    return all(m.shows(when_of(feedback, k)) for k in image_tests)


def maps_when(feedback: Feedback, image_tests: Iterable[str]) -> When:
    """When the error map and the rejected pixels are shown to a student: the latest of the image tests'."""
    return max([When.now, *(when_of(feedback, k) for k in image_tests)], key=ORDER.__getitem__)


def hidden_badge(when: When) -> str:
    return f"shown {'after the deadline' if when == When.after_deadline else 'never'}"


def appears(when: When, m: Moment, readable: bool = False) -> str:
    """When something hidden now appears, in words: its time in ISO 8601 (UTC), or `readable` as a person reads
    it in a test's output ("2026-12-09 17:00 UTC"; the page shows `at` in the student's own zone)."""
    if when == When.never:
        return "never shown to students for this assignment (your instructor sees them)"
    at = datetime.fromtimestamp(m.cut, UTC).strftime("%Y-%m-%d %H:%M UTC") if readable else iso(m.cut)
    return f"shown after the deadline, from {at}"


def _join(items: list[str]) -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def withheld(
    feedback: Feedback, tests: list[dict], image_tests: list[str], m: Moment, kind: str, measured: bool = True
) -> list[dict]:
    """What the policy hides from the student now, grouped by when it appears: each group's `when`, `at` (the
    time, ISO 8601; null for never), the hidden `tests` (their policy names), the `pictures` held back, `parts`
    (what is hidden, in words, for the page's sentence) and a `message` saying it all. `measured`: whether the
    image was compared at all (an invalid scene has no error map to hide)."""
    if m.instructor:
        return []
    groups: dict[When, dict] = {}

    def group(when: When) -> dict:
        return groups.setdefault(when, {"when": str(when), "at": None if when == When.never else iso(m.cut),
                                        "tests": [], "pictures": [], "parts": []})  # fmt: skip

    for t in tests:
        if "hidden" in t:
            g = group(when_of(feedback, t["test"]))
            g["tests"].append(t["test"])
            g["parts"].append(f"the result of \u201c{t['name']}\u201d")
    if measured and image_tests and not map_shown(feedback, image_tests, m):
        g = group(maps_when(feedback, image_tests))
        g["pictures"] = list(MAP_PICTURES)
        g["parts"] += ["the error map", "the rejected pixels", "the metrics against the noise baseline"]
        g["parts"].append("the ray trees at a pixel" if kind == "scene" else "the probe pixels of your tracer's trees")
    out = []
    for when in (When.after_deadline, When.never):
        if when in groups:
            g = groups[when]
            g["message"] = f"{_join(g['parts'])[:1].upper()}{_join(g['parts'])[1:]}: {appears(when, m)}."
            out.append(g)
    return out


def feedback_view(
    report: dict, keys: list[str], image_tests: list[str], feedback: Feedback, m: Moment, kind: str
) -> dict:
    """A graded report (its `tests` in the order of `keys`, their policy names) as the policy shows it at `m`:
    each test's score, status and output, or `hidden` with when it is shown; the metrics when the error map is
    shown, else each shown image test's "Where to look" without the pictures; `pictures` (of MAP_PICTURES) shown;
    `withheld`: what is hidden and when it appears."""
    maps = map_shown(feedback, image_tests, m)
    later = appears(maps_when(feedback, image_tests), m, readable=True)
    note = None if maps else f"The error map and the rejected pixels are {later}."
    tests = []
    for key, t in zip(keys, report.get("tests", []), strict=False):
        when = when_of(feedback, key)
        entry = {"name": t["name"], "test": key, "max_score": t["max_score"], "shown": str(when)}
        if m.shows(when):
            output = t["output"]
            if note and key in IMAGE_TESTS:
                output = where_without_pictures(output, note)
            status = t.get("status") or ("passed" if t["score"] >= t["max_score"] else "failed")  # a check's has none
            entry.update(score=t["score"], status=status, output=output)
        else:
            entry["hidden"] = hidden_badge(when)
            if when == When.after_deadline:
                entry["shown_at"] = iso(m.cut)
        tests.append(entry)
    out = {"tests": tests, "errors": report.get("errors", []), "warnings": report.get("warnings", [])}
    if maps and report.get("metrics"):
        out["metrics"] = report["metrics"]
    out["pictures"] = list(MAP_PICTURES) if maps else []
    out["withheld"] = withheld(feedback, tests, image_tests, m, kind, measured=bool(report.get("metrics")))
    return out
