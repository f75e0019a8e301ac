"""Submissions: one kept (its caps, the deadline and the late cut-off) and handed once to its version's grading
run, a check without submitting, the submissions as they count now (late by the deadline as it is now), those a
stopped server had not handed yet, and the followers of a submission's grade.

A submission's file is linked into the run's folder, then its row here and its row in the run (keyed by its own
id) are written in one transaction: a full disk keeps neither (507). A regrade hands rows again
(`INSERT OR IGNORE`): handed twice, graded once."""

from __future__ import annotations

import json
import logging
import uuid
from concurrent.futures import TimeoutError
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from functools import partial
from pathlib import Path

from server.core.errors import Forbidden, TooMany, Unavailable
from server.core.files import write_atomic
from server.course.base import DAY, CourseBase, report_keys
from server.course.people import Who
from server.course.policy import Feedback, feedback_view, map_shown
from server.course.schema import AssignmentRow, SubmissionRow, SubmissionWithGrade
from server.grading.runs import Handed
from server.jobs.service import Follower, wake_all
from tracer.grading import tasks

log = logging.getLogger(__name__)

SUFFIX = {"scene": ".json", "png": ".png", "exr": ".exr"}
CHECK_SECONDS = 30  # a check waits this long for a grading process (they are busy with a deadline's burst)


class Submissions(CourseBase):
    """Submitting, checking, the submissions, following one (mixed into server/course/service.Course)."""

    def submit(self, a: AssignmentRow, who: Who, kind: str, data: bytes, accepted: float) -> SubmissionWithGrade:
        """Keep the submission (its file, then its row: acknowledged), then hand it to the grading run."""
        if who.student is None:  # staff (who.instructor)
            raise Forbidden(
                [
                    {
                        "path": "Authorization",
                        "message": "submissions are a student's: send a student's token (the roster gives each one)",
                    }
                ],
            )
        student = who.student
        if student.get("left_at") is not None:  # the LMS's roster no longer has them (server/course/lms.py's sync)
            message = (
                "you are no longer on this course's roster in the LMS (inactive): your submissions and "
                "grades are kept and shown, but new ones are not taken; ask your instructor if this is wrong"
            )
            raise Forbidden([{"path": "student", "message": message}])
        due, cut = self.deadlines(a, student)
        decide = self.spend_plan(a, student, due, cut, accepted)  # late tokens (tokens.py): decided in the row's tx
        if accepted > cut:
            decide(self.store.db, dry=True)  # refused at once when tokens cannot cover it (nothing written yet)
        sid = uuid.uuid4().hex
        rel = f"{a['id']}/submissions/{sid}{SUFFIX[kind]}"
        path = self.root / rel
        write_atomic(path, lambda tmp: tmp.write_bytes(data))
        sub = {
            "id": sid,
            "assignment_id": a["id"],
            "student": student["student"],
            "version": a["version"],
            "run_id": a["run_id"],
            "kind": kind,
            "file": rel,
            "accepted_at": accepted,
            "late": int(accepted > due),
        }
        cap = self.settings.max_submissions_per_hour
        # its file is put into the run's folder (a link) first, then both rows go in one transaction: a full disk
        # keeps nothing (507), never a row without its grade (issue #39, item 2)
        try:
            item = self.runs.place(a["run_id"], self._handed(sub))
            try:
                refused = self.store.add_submission(sub, a["policy"]["max_submissions"], cap, accepted - 3600,
                                                    also=partial(self.runs.gs.add_item, a["run_id"], item),
                                                    before=decide)  # fmt: skip
            except BaseException:
                self.runs.unplace(a["run_id"], item)
                raise
        except BaseException:  # a full disk: nothing of it is kept (the client was not told it was taken)
            path.unlink(missing_ok=True)
            raise
        if refused is not None:
            path.unlink(missing_ok=True)
            self.runs.unplace(a["run_id"], item)
            if refused == "hour":
                message = f"at most {cap} submissions per hour (TRACER_MAX_SUBMISSIONS_PER_HOUR); try again later"
                raise TooMany([{"path": "", "message": message}], retry_after=600)
            message = (
                f"no submissions left: {a['policy']['max_submissions']} used (an invalid or ungradable "
                "submission costs none)"
            )
            raise Forbidden([{"path": "max_submissions", "message": message}])
        self.runs.added(a["run_id"])
        kept = self.submission(a, sid)
        assert kept is not None  # its row was written just above
        return kept

    def check(self, a: AssignmentRow, who: Who, kind: str, data: bytes) -> dict:
        """What a submission would get now, without submitting (no attempt, no row): validity and, for a
        scene, the requirements, in a grading process (seconds: no render), shown as the policy shows them
        now; the image tests are only named (they need the render a submission gets)."""
        folder = self.root / a["id"] / "checks"
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{uuid.uuid4().hex}{SUFFIX[kind]}"
        path.write_bytes(data)
        feedback = Feedback.model_validate(a["policy"]["feedback"])
        assignment, now = self.spec(a["id"], a["version"]), self.now()
        probes: dict = {}
        try:
            future = self.runs.pool.submit(
                tasks.prepare_submission, json.dumps(a["spec"]), "check", kind, str(path), f"check{SUFFIX[kind]}"
            )
            result = future.result(timeout=CHECK_SECONDS)
            if kind != "scene" and not result["prepared"]["report"]["errors"] and assignment.image_tests():
                probes = self._check_probes(a, who, feedback, now, path, kind)
        except (BrokenProcessPool, TimeoutError):
            raise Unavailable(
                [{"path": "", "message": "the check could not run now; try again"}], retry_after=5
            ) from None
        finally:
            path.unlink(missing_ok=True)
        report = result["prepared"]["report"]
        m = self.moment(a, who, now)
        seen = feedback_view(report, report_keys(assignment, kind), list(assignment.image_tests()), feedback, m, kind)
        valid = not report["errors"]
        return {
            "valid": valid,
            "tests": seen["tests"],
            "errors": report["errors"],
            "warnings": report["warnings"],
            "image_tests": list(assignment.image_tests()) if valid else [],
            **probes,
        }

    def _check_probes(self, a: AssignmentRow, who: Who, feedback: Feedback, now: float, path: Path, kind: str) -> dict:
        """An image's probes in the check (docs/own-tracer.md), as the policy shows the error map now: {"probes"},
        {"probes_hidden": when}, or {"probes_pending": why} while the reference is not rendered yet."""
        if not map_shown(feedback, self.spec(a["id"], a["version"]).image_tests(), self.moment(a, who, now)):
            return {"probes_hidden": self._probes_hidden(a, who, feedback)}
        folder = self.runs.folder(a["run_id"]) if a.get("run_id") else None
        mean = next((r for r in self.runs.gs.renders(a["run_id"]) if r["key"] == "mean"), None) if folder else None
        if folder is None or mean is None or mean["status"] != "done" or not mean.get("job_id"):
            return {"probes_pending": "the reference is still being rendered: the probes come with the check once "
                    "it is done, and with your submission's feedback"}  # fmt: skip
        exr = folder / "renders" / f"{mean['job_id']}.exr"
        found = self.runs.pool.submit(tasks.probe_image, json.dumps(a["spec"]), str(exr), str(path), kind)
        found = found.result(timeout=CHECK_SECONDS)
        return {"probes": found["probes"]} if "probes" in found else {"probes_pending": found["error"]}

    def submissions(self, a: AssignmentRow, student: str | None = None) -> list[SubmissionWithGrade]:
        """Submissions (one student's, or all), each `late` by the student's deadline as it is now: an
        extension granted afterwards, or an edit that moves the deadline, takes a late mark (and its penalty)
        away or gives it (the row keeps what was true when the body came)."""
        subs = self.store.submissions(a["id"], student)
        due = {s["student"]: self.deadlines(a, s)[0] for s in self.store.students(a["id"])}
        marked = _marked(subs, lambda sub: due.get(sub["student"], sub["accepted_at"]))
        return self.with_test_overrides(a, marked)  # tests' points set by regrade requests (regrade.py)

    def submission(self, a: AssignmentRow, sid: str) -> SubmissionWithGrade | None:
        sub = self.store.submission(a["id"], sid) if len(sid) == 32 else None
        if sub is not None:
            due = self.deadlines(a, self.store.student(a["id"], sub["student"]))[0]
            mine = _marked(self.store.submissions(a["id"], sub["student"]), lambda _: due)
            sub["late"] = next((s["late"] for s in mine if s["id"] == sid), int(sub["accepted_at"] > due))
            self.with_test_overrides(a, [sub])  # tests' points set by regrade requests (regrade.py)
        return sub

    def _handed(self, sub: SubmissionRow | dict) -> Handed:
        return Handed(sub["id"], sub["kind"], f"submission{SUFFIX[sub['kind']]}", path=self.root / sub["file"])

    def _hand(self, sub: SubmissionRow) -> None:
        self.runs.add(sub["run_id"], self._handed(sub))
        self.store.handed(sub["id"], sub["run_id"])

    def resume(self) -> int:
        """At start-up: the submissions a stopped server accepted but had not handed to their run."""
        subs = self.store.unhanded()
        for sub in subs:
            self._hand(sub)
        if subs:
            log.info("course: %d accepted submission(s) handed to their grading runs", len(subs))
        return len(subs)

    @contextmanager
    def follow(self, sid: str):
        """A follower of one submission, woken (from a grading run's thread) each time its grade moves."""
        follower = Follower(sid, urgent=False)
        with self._lock:
            self._followers.setdefault(sid, set()).add(follower)
        try:
            yield follower
        finally:
            with self._lock:
                mine = self._followers.get(sid, set())
                mine.discard(follower)
                if not mine:
                    self._followers.pop(sid, None)

    def _changed(self, run_id: str, student: str) -> None:
        with self._lock:
            followers = list(self._followers.get(student, ()))
        for f in followers:
            f.wake({"id": student})
        wake_all(followers)


def _marked(subs: list[SubmissionWithGrade], due_of) -> list[SubmissionWithGrade]:
    """Each submission (in the order they came) `late` after its student's deadline plus the days of late tokens
    they spent on the assignment up to it, itself included (server/course/tokens.py)."""
    covered: dict[str, int] = {}
    for sub in subs:
        covered[sub["student"]] = covered.get(sub["student"], 0) + sub["tokens_spent"]
        sub["late"] = int(sub["accepted_at"] > due_of(sub) + covered[sub["student"]] * DAY)
    return subs
