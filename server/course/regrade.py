"""Regrade requests (issue #41, item 3; docs/assignments.md "Regrade requests"): a student asks for another look at
one item of their counting submission (a test: validity, a requirement, an image test, by its policy name; or a
staff-graded item by its name), with a reason; the course's staff (instructors and TAs) answer from a queue.

- **Asking** (`request_regrade`): only the student whose submission it is; refused after the assignment's
  **regrade deadline** (`regrade_deadline` in its policy; none: a week after the student's own late cut-off, an
  extension counted: `regrade_deadline`), for an item the spec does not have, for a submission that is not the
  student's counting one (the one that is their grade), for an item whose result they cannot see yet (a test the
  feedback policy hides now, a manual item before the release), and while a request of theirs for that item of
  that submission is open.
- **Answering** (`answer_regrade`): accepted or declined, with a reply; accepted with `points` sets that item's
  points for that submission: for a manual item an override of the manual grade's points (through the manual
  grades, server/course/manual.py), for a test an override of the test's points in the auto part
  (`course_test_overrides`, applied to the submission's score wherever it is read: `with_test_overrides`, called by
  submissions.py). The grade's totals, the exports, the gradebook and the LMS's score follow (`_grade_moved`).
  Declined changes nothing but the request. A request may be answered again; every change is kept (its events:
  server/course/regrade_store.py) and audited (`regrade.request`, `regrade.answer`).
- **The queue** (`regrade_requests`): open first, oldest first, each with the student (hidden while the assignment
  grades anonymously and is not released), the item, the reason, the item's current points, the status, the reply
  and the history. A student asking gets their own.
"""

from __future__ import annotations

import logging
from datetime import datetime

from server.core.errors import Conflict, Forbidden, Invalid, NotFound
from server.course import regrade_store as rs
from server.course.audit import Target
from server.course.base import DAY, CourseBase, iso, report_keys, status_of
from server.course.people import Who
from server.course.policy import Feedback, when_of
from server.course.schema import (
    AssignmentRow,
    MemberRow,
    RegradeEvent,
    RegradeRequestRow,
    StudentRow,
    SubmissionWithGrade,
)

log = logging.getLogger(__name__)

MAX_REASON = 2000
MAX_REPLY = 4000
DEFAULT_WINDOW = 7 * DAY  # no regrade_deadline: a week after the student's late cut-off
STATUSES = (rs.OPEN, rs.ACCEPTED, rs.DECLINED)


class Regrade(CourseBase):
    """Regrade requests: asked, answered, listed; tests' points set by them (mixed into service.Course)."""

    def regrade_deadline(self, a: AssignmentRow, student: StudentRow | MemberRow | None) -> float:
        """Until when (Unix time) a student may ask: the policy's `regrade_deadline`, else a week after their late
        cut-off (their deadline without one; an extension moves it)."""
        when = a["policy"].get("regrade_deadline")
        if when:
            return datetime.fromisoformat(when).timestamp()
        return self.deadlines(a, student)[1] + DEFAULT_WINDOW

    # -- the tests' points ---------------------------------------------------------------------------------

    def _report_tests(self, a: AssignmentRow, sub: SubmissionWithGrade) -> dict[str, dict]:
        """{policy name: the report's test (name, score, max_score)} of a graded submission."""
        if status_of(sub) != "graded":
            return {}
        item = self.runs.item(sub["run_id"], sub["id"]) or {}
        tests = ((item.get("report") or {}).get("tests")) or []
        keys = report_keys(self.spec(a["id"], sub["version"]), sub["kind"])
        return dict(zip(keys, tests, strict=False))

    def with_test_overrides(self, a: AssignmentRow, subs: list[SubmissionWithGrade]) -> list[SubmissionWithGrade]:
        """Each submission's score with the tests' points accepted regrade requests set (under the version they
        were set for), clamped to 0..its maximum; `auto_score`: the grading's own."""
        found = rs.overrides(self.store, a["id"], subs[0]["id"] if len(subs) == 1 else None) if subs else {}
        for sub in subs:
            mine = found.get(sub["id"])
            score, most = sub.get("score"), sub.get("max_score")
            if not mine or score is None:
                continue
            delta = sum(o["points"] - o["original"] for o in mine.values() if o["version"] == sub["version"])
            if delta:
                most = most if most is not None else float("inf")
                sub["auto_score"] = score
                sub["score"] = round(min(most, max(0.0, score + delta)), 6)
        return subs

    def regraded_feedback(self, a: AssignmentRow, sub: SubmissionWithGrade, feedback: dict | None) -> None:
        """A view's tests with the points regrade requests set (`regraded_from`: the grading's)."""
        mine = rs.overrides(self.store, a["id"], sub["id"]).get(sub["id"], {}) if feedback else {}
        for t in (feedback or {}).get("tests", []):
            o = mine.get(t.get("test"))
            if o is not None and o["version"] == sub["version"] and "score" in t:
                t["regraded_from"], t["score"] = t["score"], o["points"]

    def _item(self, a: AssignmentRow, sub: SubmissionWithGrade, item: str) -> tuple[str, float, float | None]:
        """(kind, the most it is worth, its points now) of a submission's item; 422 naming `item` when the spec
        has no such test or manual item."""
        tests = self._report_tests(a, sub)
        if item in tests:
            t = tests[item]
            o = rs.overrides(self.store, a["id"], sub["id"]).get(sub["id"], {}).get(item)
            now = o["points"] if o is not None and o["version"] == sub["version"] else t["score"]
            return "test", t["max_score"], now
        m = self.spec(a["id"], sub["version"]).manual_item(item)
        if m is not None:
            part = self.manual_part(a, sub["id"])
            return "manual", m.points, next(i["points"] for i in part["items"] if i["name"] == item)
        names = [*tests, *(m.name for m in self.manual_items(a))]
        listed = ", ".join(map(repr, names))
        message = f"no test or staff-graded item {item[:100]!r} in this assignment; its items: {listed}"
        raise Invalid([{"path": "item", "message": message}])

    # -- asking ----------------------------------------------------------------------------------------------

    def request_regrade(self, a: AssignmentRow, sid: str, body: dict, who: Who) -> dict:
        """A student's request on one item of their counting submission (see the module's docstring for the
        refusals); the request as they see it."""
        sub = self.submission(a, sid)
        if who.student is None:
            raise Forbidden([{"path": "role", "message": "only the student whose submission it is may ask for a "
                              "regrade"}])  # fmt: skip
        if sub is None or sub["student"] != who.student["student"]:
            raise NotFound([{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
        reason = str(body.get("reason") or "").strip()
        if not reason:
            raise Invalid([{"path": "reason", "message": "expected a reason: what should be looked at again, why"}])
        if len(reason) > MAX_REASON:
            raise Invalid([{"path": "reason", "message": f"at most {MAX_REASON} characters; got {len(reason)}"}])
        item = str(body.get("item") or "")
        now, until = self.now(), self.regrade_deadline(a, who.student)
        if now > until:
            message = f"regrade requests were taken until {iso(until)}; it is {iso(now)}"
            raise Forbidden([{"path": "regrade_deadline", "message": message}])
        kind, _, points = self._item(a, sub, item)
        counting = self.counting(a, self.submissions(a, sub["student"]))
        if counting is None or counting["id"] != sub["id"]:
            which = f"submission {counting['id']}" if counting else "none yet"
            message = f"only the submission that is your grade can be regraded ({which}); this is another one"
            raise Conflict([{"path": "sid", "message": message}])
        if kind == "manual" and self.released_at(a) is None:
            raise Forbidden([{"path": "item", "message": f"the staff's grade of {item!r} is not released yet: ask "
                              "once you can see it"}])  # fmt: skip
        if kind == "test":
            when = when_of(Feedback.model_validate(a["policy"]["feedback"]), item)
            if not self.moment(a, who, now).shows(when):
                raise Forbidden([{"path": "item", "message": f"the result of {item!r} is not shown to you yet: ask "
                                  "once you can see it"}])  # fmt: skip
        req = {"assignment_id": a["id"], "submission_id": sub["id"], "student": sub["student"], "item": item,
               "kind": kind, "reason": reason, "points": points}  # fmt: skip
        target = Target(a["course_id"], a["id"], student=sub["student"], submission=sub["id"])
        row = rs.create(self.store, req, target, self.by(who))
        if row is None:
            raise Conflict([{"path": "item", "message": f"a request about {item!r} of this submission is open "
                             "already: wait for its answer"}])  # fmt: skip
        log.info("regrade request %s: %s of submission %s by %s", row["id"], item, sub["id"], sub["student"])
        return self._request_view(a, row, who, rs.events(self.store, [row["id"]])[row["id"]])

    # -- answering ---------------------------------------------------------------------------------------------

    def answer_regrade(self, a: AssignmentRow, sid: str, rid: str, body: dict, who: Who) -> dict:
        """Staff's answer (again, maybe): accepted (with `points`: that item's points for that submission) or
        declined, with a reply."""
        row = rs.one(self.store, rid) if len(rid) <= 64 else None
        if row is None or row["assignment_id"] != a["id"] or row["submission_id"] != sid:
            raise NotFound([{"path": "rid", "message": f"no regrade request with id '{rid[:64]}'"}])
        status = body.get("status")
        if status not in (rs.ACCEPTED, rs.DECLINED):
            message = f"expected 'accepted' or 'declined'; got {str(status)[:40]!r}"
            raise Invalid([{"path": "status", "message": message}])
        reply = str(body.get("reply") or "").strip()
        if not reply:
            raise Invalid([{"path": "reply", "message": "expected a reply to the student"}])
        if len(reply) > MAX_REPLY:
            raise Invalid([{"path": "reply", "message": f"at most {MAX_REPLY} characters; got {len(reply)}"}])
        new = body.get("points")
        if new is not None and status != rs.ACCEPTED:
            raise Invalid([{"path": "points", "message": "points go with an accepted answer only (declined changes "
                            "nothing but the request)"}])  # fmt: skip
        sub = self.submission(a, sid)
        if sub is None:
            raise NotFound([{"path": "sid", "message": f"no submission with id '{sid[:64]}'"}])
        points = None
        if new is not None:
            kind, most, was = self._item(a, sub, row["item"])
            if isinstance(new, bool) or not isinstance(new, int | float) or not 0 <= new <= most:
                message = f"expected points within 0..{most:g} (the item's); got {str(new)[:40]}"
                raise Invalid([{"path": "points", "message": message}])
            points = {"before": was, "after": float(new)}
            if kind == "test":
                original = self._report_tests(a, sub)[row["item"]]["score"]
                points["test"] = {"version": sub["version"], "original": original}
        target = Target(a["course_id"], a["id"], student=sub["student"], submission=sub["id"])
        rs.answer(self.store, rid, status, reply, points, target, self.by(who, reply))
        if points is not None:
            if "test" in points:
                self._grade_moved(sub)
            else:  # the manual grade's override, through the manual grades (their own record, the LMS)
                grade = self.store.manual_grades(a["id"], sub["id"]).get(sub["id"], {}).get(row["item"])
                self._set_manual_grade(
                    a, sub, row["item"],
                    {"rubric": grade["rubric"] if grade else [], "points": points["after"],
                     "comment": grade["comment"] if grade else "", "grader": who.person},
                    who,
                )  # fmt: skip
        log.info("regrade request %s %s by %s", rid, status, who.person or who.role)
        row = rs.one(self.store, rid) or row
        return self._request_view(a, row, who, rs.events(self.store, [rid])[rid])

    # -- reading -------------------------------------------------------------------------------------------------

    def regrade_requests(self, a: AssignmentRow, who: Who, status: str | None = None, sid: str | None = None) -> dict:
        """The queue (staff: everyone's; a student: their own), open first, then oldest first; `status` one of
        open, accepted, declined; `sid` one submission's."""
        if status is not None and status not in STATUSES:
            message = f"expected one of {', '.join(STATUSES)}; got {status[:40]!r}"
            raise Invalid([{"path": "status", "message": message}])
        student = who.student["student"] if who.student is not None else None
        rows = rs.of_assignment(self.store, a["id"], student, status)
        if sid is not None:
            rows = [r for r in rows if r["submission_id"] == sid]
        history = rs.events(self.store, [r["id"] for r in rows])
        until = self.regrade_deadline(a, who.student) if who.student is not None else None
        staff = self._staff_context(a) if who.student is None else None
        return {"requests": [self._request_view(a, r, who, history[r["id"]], staff) for r in rows],
                "regrade_deadline": iso(until) if until is not None else None,
                "regrade_open": None if until is None else self.now() <= until}  # fmt: skip

    def _staff_context(self, a: AssignmentRow) -> dict:
        """What staff's view of every request reads once: anonymity, the roster's order and names."""
        state = self.store.manual_state(a["id"])
        roster = self.store.students(a["id"])
        return {"hidden": bool(state["anonymous"]) and state["released_at"] is None,
                "number": {st["student"]: i + 1 for i, st in enumerate(roster)},
                "name": {st["student"]: st["name"] for st in roster}}  # fmt: skip

    def _request_view(
        self, a: AssignmentRow, row: RegradeRequestRow, who: Who, history: list[RegradeEvent], staff: dict | None = None
    ) -> dict:
        sub = self.submission(a, row["submission_id"])
        current = most = None
        if sub is not None:
            try:
                _, most, current = self._item(a, sub, row["item"])
            except Invalid:  # an edit removed the item: the request stays, with no points now
                pass
        out = {
            "id": row["id"],
            "submission": row["submission_id"],
            "item": row["item"],
            "kind": row["kind"],
            "reason": row["reason"],
            "status": row["status"],
            "reply": row["reply"],
            "points": current,
            "max_points": most,
            "asked_at": iso(row["created_at"]),
            "answered_at": iso(row["answered_at"]),
            "history": [{**e, "at": iso(e["at"])} for e in history],
            "url": f"/api/assignments/{a['id']}/submissions/{row['submission_id']}/regrade-requests/{row['id']}",
        }
        if who.student is None:
            staff = staff or self._staff_context(a)
            hidden = staff["hidden"]
            name = staff["name"].get(row["student"], row["student"])
            number = staff["number"].get(row["student"], 0)
            out["student"] = None if hidden else {"id": row["student"], "name": name}
            out["label"] = f"Student {number}" if hidden else name
            out["answered_by"] = row["answered_by"]
            if hidden:  # the trail names the student; the queue does not
                out["history"] = [{**e, "who": "student" if e["who"].startswith("student:") else e["who"]}
                                  for e in out["history"]]  # fmt: skip
        return out
