"""What a caller may see of a submission: its score when the feedback policy shows it, each test's feedback by its
own rule, the pictures they may fetch (the error map only when no image test is hidden), the probe pixels with
the error map; everything to the course's staff."""

from __future__ import annotations

from pathlib import Path

from server.course import policy
from server.course.base import CourseBase, iso, report_keys, status_of
from server.course.people import Who
from server.course.policy import Feedback, When, feedback_view, map_shown
from server.course.schema import AssignmentRow, SubmissionWithGrade


class Views(CourseBase):
    """A submission as the caller may see it (mixed into server/course/service.Course)."""

    def view(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who, counting: str | None = None) -> dict:
        """A submission as the caller may see it: the score when the policy shows it, each test's feedback by
        its own rule; everything to the instructor."""
        p, now = a["policy"], self.now()
        feedback = Feedback.model_validate(p["feedback"])
        status = status_of(sub)
        penalty = p["late_penalty"] if sub["late"] else 0.0
        show_score = self.shown(feedback.score_when(), a, who, now) and status in ("graded", "invalid", "failed")
        out = {
            "id": sub["id"],
            "student": sub["student"],
            "status": status,
            "kind": sub["kind"],
            "version": sub["version"],
            "accepted_at": iso(sub["accepted_at"]),
            "late": bool(sub["late"]),
            "tokens_spent": sub.get("tokens_spent", 0),
            "counts_as_attempt": status not in ("invalid", "failed"),
            "counts": sub["id"] == counting,
            "score": round(sub["score"] * (1 - penalty), 6) if show_score and sub["score"] is not None else None,
            "raw_score": sub["score"] if show_score else None,
            "penalty": penalty,
            "max_score": sub["max_score"],
            "feedback": None,
            "url": f"/api/assignments/{a['id']}/submissions/{sub['id']}",
        }
        if status in ("graded", "invalid", "failed"):
            item = self.runs.item(sub["run_id"], sub["id"])
            report = (item or {}).get("report") or {}
            out["feedback"] = self._feedback(a, sub, report, feedback, who, now)
            self.regraded_feedback(a, sub, out["feedback"])  # tests' points set by regrade requests
            out["files"] = {name: f"{out['url']}/{name}" for name in self.files(a, sub, who)}
        manual = self.manual_view(a, sub, who)
        if manual is not None:  # staff-graded items (server/course/manual.py): the student's after the release
            out["manual"] = manual
            total = self.total(a, sub) if out["score"] is not None else None
            out["total"] = None if total is None else round(total[0], 6)
            out["total_max"] = None if total is None else total[1]
        return out

    def view_one(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who) -> dict:
        """`view` of one submission, with whether it is the one that counts among its student's."""
        c = self.counting(a, self.submissions(a, sub["student"]))
        return self.view(a, sub, who, c["id"] if c else None)

    def files(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who) -> list[str]:
        """The pictures of a graded submission the caller may fetch: its render (their own work); the error
        map and the rejected pixels when no image test is hidden (they show the reference's structure); the
        reference when the policy shows it. The instructor: all of them."""
        if status_of(sub) != "graded":
            return []
        feedback = Feedback.model_validate(a["policy"]["feedback"])
        now = self.now()
        names = ["render.png"]
        if map_shown(feedback, self.spec(a["id"], sub["version"]).image_tests(), self.moment(a, who, now)):
            names += list(policy.MAP_PICTURES)
        if who.instructor or a["policy"]["show_reference"]:
            names.append("reference.png")
        folder = self.runs.root / sub["run_id"] / "out" / sub["id"]
        return [n for n in names if (folder / n).is_file()]

    def file(self, a: AssignmentRow, sub: SubmissionWithGrade, who: Who, name: str) -> Path | None:
        if name not in self.files(a, sub, who):
            return None
        return self.runs.root / sub["run_id"] / "out" / sub["id"] / name

    def _feedback(
        self, a: AssignmentRow, sub: SubmissionWithGrade, report: dict, feedback: Feedback, who: Who, now: float
    ) -> dict:
        """The report as the policy shows it to the caller now (policy.feedback_view: the one rule, shared with the
        publish form's preview), with the probes of an image from the student's own tracer."""
        spec = self.spec(a["id"], sub["version"])
        keys, image_tests = report_keys(spec, sub["kind"]), list(spec.image_tests())
        out = feedback_view(report, keys, image_tests, feedback, self.moment(a, who, now), sub["kind"])
        probes = (report.get("metrics") or {}).get("probes")
        if probes is not None and out["pictures"]:  # shown with the error map (docs/own-tracer.md)
            out["probes"] = probes
        elif probes is not None:
            out["probes_hidden"] = self._probes_hidden(a, who, feedback)
        return out

    def _probes_hidden(self, a: AssignmentRow, who: Who, feedback: Feedback) -> str:
        """When the probe pixels appear, for a student to whom the error map is hidden now."""
        tests = self.spec(a["id"], a["version"]).image_tests()
        if any(feedback.tests.get(k, feedback.default) == When.never for k in tests):
            when = "never, for this assignment"
        elif who.student:
            when = f"after your deadline, from {iso(self.deadlines(a, who.student)[1])}"
        else:
            when = "after the deadline"
        return f"the probe pixels are shown with the error map: {when}"
