"""What every part of the course service shares: its state (the store, the tokens, the grading runs, the clock, the
parsed specs), an assignment and a course looked up (404 for an unknown id), a version's spec, a student's deadlines
and whether feedback is shown now, and the small helpers of the views (`iso`, `status_of`, `report_keys`).

The concepts are mixins of `CourseBase`, each in its module (courses.py, roster.py, assignments.py,
submissions.py, views.py, grades.py); server/course/service.py joins them into the one `Course` the app holds.

**The audit trail**: a change's store method records its event in the change's transaction with the `By` that
`by(who, why)` gives (server/course/audit.py); `audit_trail(cid, ...)` reads a course's events.

**Time** is `clock()`, the app's `state.clock` (UTC now; tests set it): a submission's time is the clock when
its body was accepted, and the deadline, the late mark and the feedback shown follow it.
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Callable
from datetime import datetime
from typing import TYPE_CHECKING, Protocol

from server.core.errors import NotFound
from server.core.settings import Settings
from server.course import audit, policy
from server.course.people import TokenMaker, Who
from server.course.policy import Feedback, Moment
from server.course.schema import (
    AssignmentRow,
    AuditEvent,
    CourseRow,
    ManualGrade,
    ManualGradeRow,
    MemberRow,
    StudentRow,
    SubmissionRow,
    SubmissionWithGrade,
)
from server.course.store import CourseStore
from server.grading.runs import GradeRuns
from server.grading.store import GradingItemRow
from server.jobs.service import Follower
from tracer.grading import Assignment, load_assignment

DAY = 86400.0  # a late token's worth (server/course/tokens.py)
REFERENCE = "reference"  # the reference scene's row in a version's grading run (submission ids are hex)


class Decide(Protocol):
    """A late submission's tokens decided in its row's transaction (tokens.py's spend_plan); `dry`: only refused."""

    def __call__(self, db: sqlite3.Connection, dry: bool = False) -> dict: ...


def not_found(what: str, key: str) -> NotFound:
    return NotFound([{"path": "id", "message": f"no {what} with id '{key[:64]}'"}])


iso = policy.iso


class CourseBase:
    """The state and the lookups every concept's mixin uses."""

    def __init__(self, settings: Settings, runs: GradeRuns, clock: Callable[[], datetime]):
        self.settings, self.runs, self.clock = settings, runs, clock
        self.store = CourseStore(settings.data_dir, self.now())
        self.tokens = TokenMaker(settings.data_dir / "keys")
        self.root = settings.data_dir / "course"
        self.root.mkdir(parents=True, exist_ok=True)
        self._specs: dict[tuple[str, int], Assignment] = {}  # a version's spec, parsed (versions never change)
        self._followers: dict[str, set[Follower]] = {}  # a submission's event streams, by its id
        self._lock = threading.Lock()

    def now(self) -> float:
        return self.clock().timestamp()

    if TYPE_CHECKING:  # what one concept's mixin calls of another's, for the type checker (service.Course has them)

        def course_link(self, base: str, cid: str, token: str, staff: bool = False) -> str: ...  # roster.py
        def token_of(self, cid: str, kind: str, person: str, gen: int) -> str: ...  # roster.py
        def submission(self, a: AssignmentRow, sid: str) -> SubmissionWithGrade | None: ...  # submissions.py
        def submissions(
            self, a: AssignmentRow, student: str | None = None
        ) -> list[SubmissionWithGrade]: ...  # submissions.py
        def _hand(self, sub: SubmissionRow) -> None: ...  # submissions.py
        def view(
            self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who, counting: str | None = None
        ) -> dict: ...  # views.py
        def _probes_hidden(self, a: AssignmentRow, who: Who, feedback: Feedback) -> str: ...  # views.py
        def counting(
            self, a: AssignmentRow, subs: list[SubmissionWithGrade]
        ) -> SubmissionWithGrade | None: ...  # grades.py
        def total(self, a: AssignmentRow, sub: SubmissionWithGrade) -> tuple[float, float]: ...  # grades.py
        def class_grades(
            self, a: AssignmentRow
        ) -> list[
            tuple[StudentRow, list[SubmissionWithGrade], SubmissionWithGrade | None, float | None]
        ]: ...  # grades.py
        def tokens_brief(self, a: AssignmentRow, student: StudentRow | MemberRow, now: float) -> dict: ...  # tokens.py
        def spend_plan(  # tokens.py
            self, a: AssignmentRow, student: StudentRow | MemberRow, due: float, cut: float, accepted: float
        ) -> Decide: ...
        def released_at(self, a: AssignmentRow) -> float | None: ...  # manual.py
        def released_manual(self, a: AssignmentRow, sub: SubmissionWithGrade) -> float | None: ...  # manual.py
        def manual_view(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who) -> dict | None: ...  # manual.py
        def manual_items(self, a: AssignmentRow) -> list: ...  # manual.py
        def manual_part(
            self, a: AssignmentRow, sid: str, rows: dict[str, ManualGradeRow] | None = None
        ) -> dict: ...  # manual.py
        def _set_manual_grade(
            self, a: AssignmentRow, sub: SubmissionWithGrade, item: str, row: ManualGrade, who: Who
        ) -> None: ...  # manual.py
        def _grade_moved(self, sub: SubmissionWithGrade) -> None: ...  # manual.py
        def regrade_deadline(self, a: AssignmentRow, student: StudentRow | MemberRow | None) -> float: ...  # regrade.py
        def with_test_overrides(
            self, a: AssignmentRow, subs: list[SubmissionWithGrade]
        ) -> list[SubmissionWithGrade]: ...  # regrade.py
        def regraded_feedback(
            self, a: AssignmentRow, sub: SubmissionWithGrade, feedback: dict | None
        ) -> None: ...  # regrade.py

    def by(self, who: Who | str | None, why: str = "") -> audit.By:
        """Who makes a change now, and why: what the store's changing methods record their audit events with
        (server/course/audit.py). `who` a caller, or a name ("lms"); None: "system" (nothing goes unrecorded)."""
        name = who if isinstance(who, str) else "system" if who is None else audit.who_of(who)
        return audit.By(name, self.now(), " ".join((why or "").split()))

    def audit_trail(self, cid: str, **filters) -> list[AuditEvent]:
        """The course's audit events, newest first (audit.events: student, assignment, limit, before)."""
        return audit.events(self.store.db, cid, **filters)

    def assignment(self, aid: str) -> AssignmentRow:
        a = self.store.assignment(aid) if len(aid) == 32 else None
        if a is None:
            raise not_found("assignment", aid)
        return a

    def course(self, cid: str) -> CourseRow:
        c = self.store.course(cid) if isinstance(cid, str) and len(cid) <= 40 else None
        if c is None:
            raise NotFound([{"path": "course", "message": f"no course with id '{str(cid)[:64]}'"}])
        return c

    def spec(self, aid: str, version: int) -> Assignment:
        """A version's spec, parsed once."""
        key = (aid, version)
        if key not in self._specs:
            row = next(v for v in self.store.versions(aid) if v["version"] == version)
            self._specs[key] = load_assignment(row["spec"])[0]
        return self._specs[key]

    @staticmethod
    def deadlines(a: AssignmentRow | dict, student: StudentRow | MemberRow | None) -> tuple[float, float]:
        """(the student's deadline, their late cut-off) as Unix times: an extension moves both by as much. (A
        member row, a course's Who, has no extension: assignments' callers hold their roster row. `a` a dict: a
        preview's, its policy alone, before there is an assignment.)"""
        p = a["policy"]
        due = datetime.fromisoformat(p["deadline"]).timestamp()
        cut = datetime.fromisoformat(p["late_until"]).timestamp() if p["late_until"] else due
        extension = student.get("deadline") if student is not None else None
        if extension is not None:
            shift = extension - due
            due, cut = extension, max(extension, cut + shift)
        return due, cut

    def moment(self, a: AssignmentRow, who: Who, now: float) -> Moment:
        """The caller at `now`, as the feedback policy sees them (server/course/policy.py)."""
        return Moment(now, self.deadlines(a, who.student)[1], who.instructor)

    def shown(self, when: str, a: AssignmentRow, who: Who, now: float) -> bool:
        return self.moment(a, who, now).shows(when)


def status_of(sub: SubmissionWithGrade | GradingItemRow | dict) -> str:
    """queued (not yet taken up), grading, or the report's: graded, invalid, failed."""
    stage = sub.get("stage")
    if stage is None or stage == "submitted":
        return "queued"
    if stage != "graded":
        return "grading"
    return sub["status"] or "failed"


def report_keys(assignment, kind: str) -> list[str]:
    """The policy's name of each test of a report, in the report's order (an image has no requirements)."""
    requirements = [r.name for r in assignment.requirements] if kind == "scene" else []
    return ["validity", *requirements, *assignment.image_tests()]
