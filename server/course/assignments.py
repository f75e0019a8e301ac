"""Assignments: publishing and editing (each a new version with its own open grading run; the earlier ones kept),
a regrade, and an assignment's brief as the caller may see it.

**Graded once, the reference shared.** Each version of an assignment has one *open* grading run
(server/grading/runs.py, `GradeRuns.start(..., open_=True)`): it renders the reference mean as soon as the
version is published, grades the reference scene itself (the instructor's check that it earns full marks,
and the source of the reference image), then takes each submission as one more student of that run. So the
reference is rendered once per version and each noise baseline once per (sampler, spp, light samples) of
the version, whatever the number of submissions; every render is a batch-lane job; and the run's rows
make it durable: a restarted server resumes it."""

from __future__ import annotations

import json
import logging
import uuid
from pathlib import Path

from server.core.errors import Invalid
from server.course.base import REFERENCE, CourseBase, iso, report_keys, status_of
from server.course.people import Who
from server.course.policy import AssignmentIn, Feedback, Moment, Policy, feedback_view
from server.course.schema import AssignmentRow
from server.course.store import DEFAULT_COURSE
from server.grading.runs import Handed
from server.grading.store import GradingItemRow
from tracer.grading import AssignmentError, Grader, load_assignment
from tracer.grading.imagetests import example_misses
from tracer.grading.submission import Submission

log = logging.getLogger(__name__)


class Assignments(CourseBase):
    """Publishing, editing and regrading; the brief (mixed into server/course/service.Course)."""

    def _checked(self, body: AssignmentIn) -> tuple[str, dict]:
        """The spec as JSON text with its reference inline, and the policy to keep (422 with paths)."""
        spec = json.loads(json.dumps(body.spec))
        ref = spec.get("reference")
        if body.reference is not None:
            if not isinstance(ref, dict):
                raise Invalid([{"path": "reference", "message": "the spec has no 'reference' for this scene"}])
            ref["scene"] = body.reference
        elif isinstance(ref, dict) and isinstance(ref.get("scene"), str):
            message = (
                f"the reference scene is a file name ({ref['scene'][:80]!r}): send the scene inline, or beside the "
                "spec as 'reference' (a JSON field, or a multipart part)"
            )
            raise Invalid([{"path": "spec.reference.scene", "message": message}])
        try:
            assignment, _ = load_assignment(spec)
            Grader(assignment, None)  # the reference scene validates
        except AssignmentError as e:
            raise Invalid(
                [{"path": "spec" + ("." + x["path"] if x["path"] else ""), "message": x["message"]} for x in e.errors],
            ) from None
        keys = test_keys(assignment)
        unknown = [k for k in body.feedback.tests if k not in keys]
        if unknown:
            message = f"no test named {unknown[0]!r} in the spec; the tests: {', '.join(keys)}"
            raise Invalid([{"path": f"feedback.tests.{unknown[0]}", "message": message}])
        if body.starter is not None:
            from tracer.scene import SceneError, load_scene

            try:
                load_scene(body.starter, assignment.limits.scene_limits())
            except SceneError as e:
                raise Invalid(
                    [
                        {"path": "starter" + ("." + x["path"] if x["path"] else ""), "message": x["message"]}
                        for x in e.errors
                    ],
                ) from None
        policy = Policy.model_validate(body.model_dump(exclude={"spec", "reference"})).stored()
        return json.dumps(spec), policy

    def preview(self, body: AssignmentIn) -> dict:
        """What a student will see under `body`'s policy, before it is published (the publish form's preview):
        the feedback of an example scene submission until the deadline and after it, through the same
        policy.feedback_view as every submission's. The example: the reference scene itself (the starter's
        when there is no reference) for validity and the requirements, checked as a submission's are, and for
        the image tests the grader's own words for a render that misses the reference (example numbers; its
        "Where to look" lines are the ones a hidden picture would leave pointing at nothing)."""
        spec_text, stored = self._checked(body)
        assignment, _ = load_assignment(spec_text)
        spec = json.loads(spec_text)
        stand_in = (spec.get("reference") or {}).get("scene") or stored["starter"]
        tests: list[dict] = []
        if stand_in is not None:
            prepared = Grader(assignment, None).prepare(Submission("example", json.dumps(stand_in).encode()))
            tests = [t.to_json() for t in prepared.report.tests]
        else:  # nothing to check: the tests by name, as passed
            names = [("valid scene", assignment.validity.points)] + [
                (r.name, r.points) for r in assignment.requirements
            ]
            tests = [{"name": n, "score": p, "max_score": p, "status": "passed", "output": "passed"} for n, p in names]
        misses, metrics = example_misses(assignment, "scene")
        tests += [t.to_json() for t in misses]
        report = {"tests": tests, "errors": [], "warnings": [], "metrics": metrics}
        feedback = Feedback.model_validate(stored["feedback"])
        due, cut = self.deadlines({"policy": stored}, None)
        keys, image_tests = report_keys(assignment, "scene"), list(assignment.image_tests())
        moments = []
        for name, m in (("now", Moment(cut - 1, cut)), ("after_deadline", Moment(cut, cut))):
            seen = feedback_view(report, keys, image_tests, feedback, m, "scene")
            shown = m.shows(feedback.score_when())
            total = sum(t["score"] for t in tests)
            moments.append({"moment": name, "score": total if shown else None, "max_score": assignment.max_score(),
                            "score_shown": shown, "feedback": seen})  # fmt: skip
        return {
            "example": "the reference scene as a scene submission for validity and the requirements; for the image "
            "tests, a render that misses the reference (example numbers)",
            "deadline": iso(due),
            "cut_off": iso(cut),
            "moments": moments,
        }

    def _open_run(self, spec_text: str) -> str:
        spec = json.loads(spec_text)
        handed = []
        if spec.get("reference"):
            scene = json.dumps(spec["reference"]["scene"]).encode()
            handed.append(Handed(REFERENCE, "scene", "reference.json", scene))
        return self.runs.start(spec, handed, open_=True)["id"]

    def publish(self, body: AssignmentIn, cid: str = DEFAULT_COURSE, who: Who | None = None) -> AssignmentRow:
        """A new assignment of course `cid` (its roster: the course's members enrolled in every assignment); a
        `publish` audit event."""
        self.course(cid)
        spec, policy = self._checked(body)
        aid = uuid.uuid4().hex
        run_id = self._open_run(spec)
        try:
            self.store.create(aid, spec, policy, run_id, self.now(), cid, by=self.by(who))
        except BaseException:  # a full disk: the run ends (its reference is graded), no assignment is left
            self.runs.close(run_id)
            raise
        log.info("assignment %s published (grading run %s)", aid, run_id)
        return self.assignment(aid)

    def edit(self, aid: str, body: AssignmentIn, regrade: bool, who: Who | None = None, why: str = "") -> AssignmentRow:
        """A new version (the earlier ones are kept); `regrade`: every submission graded again under it, as
        rows of its grading run (durable as any). Audit events: `edit`, and `regrade` with `regrade`."""
        self.assignment(aid)  # 404 for an unknown one
        spec, policy = self._checked(body)
        run_id = self._open_run(spec)
        try:
            version = self.store.add_version(aid, spec, policy, run_id, self.now(), by=self.by(who, why))
        except BaseException:
            self.runs.close(run_id)
            raise
        # the old version's run stays open: a submission accepted under it a moment ago is still handed to
        # it and graded (closing it could let its thread end first); an idle open run costs a look a second
        if regrade:
            for sub in self.store.regrade(aid, version, run_id, by=self.by(who, why or "edited")):
                self._hand(sub)
        return self.assignment(aid)

    def regrade(self, aid: str, who: Who | None = None, why: str = "") -> AssignmentRow:
        """Every submission graded again: a new version with the same spec and policy, and its own run (the
        earlier grades stay in their version's run); a `regrade` audit event."""
        a = self.assignment(aid)
        spec = json.dumps(a["spec"])
        run_id = self._open_run(spec)
        try:
            version = self.store.add_version(aid, spec, a["policy"], run_id, self.now())
        except BaseException:
            self.runs.close(run_id)
            raise
        for sub in self.store.regrade(aid, version, run_id, by=self.by(who, why)):
            self._hand(sub)
        log.info("assignment %s regraded as version %d (grading run %s)", aid, version, run_id)
        return self.assignment(aid)

    def brief(self, a: AssignmentRow, who: Who, base: str) -> dict:
        spec, p, now = a["spec"], a["policy"], self.now()
        due, cut = self.deadlines(a, who.student)
        assignment = self.spec(a["id"], a["version"])
        out = {
            "id": a["id"],
            "version": a["version"],
            "name": spec["name"],
            "description": spec.get("description"),
            "requirements": [
                {"name": r.name, "points": r.points, "description": r.description} for r in assignment.requirements
            ],
            "image_tests": [{"name": k, "points": t.points} for k, t in assignment.image_tests().items()],
            "validity": {"points": assignment.validity.points},
            "max_score": assignment.max_score(),
            "render": assignment.render.model_dump(exclude_none=True),
            "limits": assignment.limits.model_dump(),
            "deadline": iso(due),
            "late_until": iso(cut) if cut > due else None,
            "late_penalty": p["late_penalty"],
            "regrade_deadline": iso(self.regrade_deadline(a, who.student)),
            "time_left": max(0.0, due - now),
            "late_time_left": max(0.0, cut - now) if cut > due else None,
            "closed": now > cut,
            "counts": p["counts"],
            "max_submissions": p["max_submissions"],
            "starter": p["starter"],
            "open": p["open"],
            "reference_image": f"/api/assignments/{a['id']}/reference.png"
            if p["show_reference"] or who.instructor
            else None,
            "feedback": p["feedback"],
        }
        if who.student is None:  # staff (who.instructor)
            out.update(
                # the caller's role (admin, instructor or ta) and what it may change, so that the page shows a TA
                # no form the server would refuse (a TA follows the class, grants extensions and regrades)
                you={"role": who.role, "may": {k: who.may(k) for k in ("publish", "roster", "extend", "regrade")}},
                spec=spec,
                policy=p,
                run_id=a["run_id"],
                students=len(self.store.students(a["id"])),
                versions=[
                    {"version": v["version"], "created_at": iso(v["version_at"]), "run_id": v["run_id"]}
                    for v in self.store.versions(a["id"])
                ],
            )
            if p["open"]:
                out["join"] = f"{base.rstrip('/')}/assignments/{a['id']}"
            ref = self.runs.item(a["run_id"], REFERENCE)
            out["reference_grade"] = _grade(ref) if ref else None
        else:
            s = who.student
            used = self.store.attempts(a["id"], s["student"])
            left = None if p["max_submissions"] is None else max(0, p["max_submissions"] - used)
            out.update(
                student={"id": s["student"], "name": s["name"], "self_declared": bool(s["self_declared"])},
                submissions_left=left,
                attempts_used=used,
                **self.tokens_brief(a, s, now),
            )
            if s.get("left_at") is not None:  # gone from the LMS course: may read all of theirs, not submit
                out["inactive"] = True
        return out

    def reference_png(self, a: AssignmentRow) -> Path | None:
        """The reference image, once the version's reference is graded (its pictures are written whole by then)."""
        ref = self.runs.gs.item(a["run_id"], REFERENCE)
        path = self.runs.root / a["run_id"] / "out" / REFERENCE / "reference.png"
        return path if ref is not None and ref["stage"] == "graded" and path.is_file() else None


def _grade(item: GradingItemRow) -> dict:
    return {
        "status": item["status"] if item["stage"] == "graded" else status_of(item),
        "score": item["score"],
        "max_score": item["max_score"],
    }


def test_keys(assignment) -> list[str]:
    """The names a feedback policy may give tests: validity, the requirements', the image tests'."""
    return ["validity", *(r.name for r in assignment.requirements), *assignment.image_tests()]
