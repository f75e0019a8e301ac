"""Similarity reports of an assignment on the service (POST and GET /api/assignments/{aid}/similarity,
docs/assignments.md): the method is tracer/grading/similarity.py's; this module says who may ask, what is
compared, bounds the cost before any work, runs it in a grading process and keeps the answer.

**Who.** The course's staff (instructors and TAs: following the class is a TA's too). A student of the
assignment gets 403 (it is their assignment: its existence is no secret to them); anyone else what the other
staff routes answer (the 404 of an unknown id, 401 or 403).

**What.** Each roster student's latest submission (a scene, or an image for an open-ended task), whatever its
grade: what they handed in last is what a person would look at. The assignment's starter scene is the scene
everyone was given, so its facts are no evidence.

**Cost, checked before the work.** At most MAX_STUDENTS submissions and MAX_BYTES of files (413 past either),
and at most MAX_RUNNING reports computing at once over the server (429 with Retry-After); a second POST while
an assignment's report is computing answers that one's status. The work runs in the grading processes
(server/grading/pool.py), never in the API's, as plain data: the files' paths and the starter as JSON.

**Kept.** The latest report of each assignment is kept beside its submissions (DATA/course/<aid>/similarity.json),
with when it was made (the course's clock) and how many submissions came since (`since`)."""

from __future__ import annotations

import json
import logging
import threading
from concurrent.futures import Future
from pathlib import Path

from server.core.errors import Forbidden, TooLarge, TooMany
from server.core.files import write_atomic
from server.core.security import Caller
from server.course.base import iso
from server.course.courses import Check
from server.course.schema import AssignmentRow, SubmissionWithGrade
from server.course.service import Course
from tracer.grading import similarity

log = logging.getLogger(__name__)

REPORT = "similarity.json"
MAX_STUDENTS = 3000  # submissions in one report: a large course's class (300 take seconds: bench/similarity.py)
MAX_BYTES = 512 * 1024 * 1024  # of their files, read by one grading process
MAX_RUNNING = 2  # reports computing at once over the server (each holds a grading process)
RETRY_AFTER = 30  # seconds, when MAX_RUNNING are computing
NOTE = (
    "A flagged pair is a pair of submissions much closer to each other than this class's usual: for a person to "
    "look at, side by side, with what they know of the students and the task. It is not a finding of misconduct: "
    "students may share a tutorial, a study group's scene or an idea they were allowed to share."
)
HOW = (
    "Scenes are compared as sets of facts (each object's and light's fields, keyed by its kind and place, its "
    "material by its values; names and order ignored; numbers on a grid), less the starter scene's facts and those "
    "that at least 20% of the class share; distance = 1 - Jaccard. Candidate pairs by MinHash with banding (LSH), "
    "then the exact distance. Images by the RMS difference of the pictures in grey at 32 x 32. `typical` is the "
    "median of the students' nearest-neighbour distances; a pair is flagged at or below `threshold` = typical / "
    "e^(3 spread), spread being 1.4826 x the median absolute deviation of those distances' logarithms (at least "
    "0.1), and never above half of typical. Fewer than 5 students compared: nothing is flagged."
)


class Reports:
    """The similarity reports of every assignment: asked for, computing, kept."""

    def __init__(self, course: Course):
        self.course = course
        self._lock = threading.Lock()
        self._running: dict[str, dict] = {}  # assignment -> its status while computing
        self._failed: dict[str, dict] = {}  # assignment -> why its last report failed (until the next one)

    def path(self, aid: str) -> Path:
        return self.course.root / aid / REPORT

    def _staff(self, aid: str, caller: Caller, instructor: Check) -> AssignmentRow:
        self.course.assignment(aid)  # 404 for an unknown one first
        if caller.owner and self.course.store.by_token(aid, caller.owner) is not None:
            raise Forbidden.at("Authorization", "similarity reports are for the course's staff")
        return self.course.staff(aid, caller, instructor, "follow")[0]

    def _latest(self, a: AssignmentRow) -> list[tuple[str, str, str]]:
        """Each roster student's latest submission as (student, kind, its file's path)."""
        latest: dict[str, SubmissionWithGrade] = {}
        for sub in self.course.store.submissions(a["id"]):  # in the order they came
            latest[sub["student"]] = sub
        roster = {s["student"] for s in self.course.store.students(a["id"])}
        return [(st, sub["kind"], str(self.course.root / sub["file"])) for st, sub in latest.items() if st in roster]

    def ask(self, aid: str, caller: Caller, instructor: Check) -> dict:
        """Start a report (202): bounded before any work; the status of the one computing if there is one."""
        a = self._staff(aid, caller, instructor)
        with self._lock:
            if aid in self._running:
                return self._running[aid]
            if len(self._running) >= MAX_RUNNING:
                raise TooMany.at("", f"{MAX_RUNNING} similarity reports are computing: ask again in a minute",
                                 retry_after=RETRY_AFTER)  # fmt: skip
            items = self._latest(a)
            if len(items) > MAX_STUDENTS:
                raise TooLarge.at("", f"{len(items)} students' submissions: a report compares at most {MAX_STUDENTS}")
            size = sum(Path(p).stat().st_size for _, _, p in items if Path(p).is_file())
            if size > MAX_BYTES:
                raise TooLarge.at("", f"the submissions' files hold {size} bytes; a report reads at most {MAX_BYTES}")
            items = [(st, kind, p) for st, kind, p in items if Path(p).is_file()]
            status = {"status": "computing", "started_at": iso(self.course.now()), "students": len(items)}
            self._running[aid] = status
            self._failed.pop(aid, None)
        starter = a["policy"].get("starter")
        try:
            future = self.course.runs.pool.submit(
                similarity.report_files, items, json.dumps(starter) if starter is not None else None
            )
        except BaseException:
            with self._lock:
                self._running.pop(aid, None)
            raise
        future.add_done_callback(lambda f: self._done(aid, f))
        log.info("similarity report of assignment %s: %d submissions, computing", aid, len(items))
        return status

    def _done(self, aid: str, future: Future) -> None:
        """Keep the report (a grading process's thread calls this): or say why there is none."""
        try:
            report = future.result()
            now = self.course.now()
            report.update(status="done", computed_at=iso(now), computed_ts=now, note=NOTE, how=HOW)
            write_atomic(self.path(aid), lambda tmp: tmp.write_text(json.dumps(report)))
            log.info("similarity report of assignment %s: %d pairs flagged", aid, len(report["pairs"]))
        except Exception as e:  # a broken pool, a full disk: the report failed, the server goes on
            log.exception("similarity report of assignment %s failed", aid)
            with self._lock:
                self._failed[aid] = {"status": "failed", "error": f"{type(e).__name__}: {str(e)[:300]}"}
        finally:
            with self._lock:
                self._running.pop(aid, None)

    def get(self, aid: str, caller: Caller, instructor: Check) -> dict:
        """The latest report (`status` done), or `computing` (with the last one's pairs, if any), `failed`, or
        `none` (never asked for)."""
        a = self._staff(aid, caller, instructor)
        with self._lock:
            running, failed = self._running.get(aid), self._failed.get(aid)
        try:
            report = json.loads(self.path(aid).read_text())
        except FileNotFoundError:
            report = None
        if report is not None:
            done = report.pop("computed_ts")
            report["since"] = sum(1 for s in self.course.store.submissions(a["id"]) if s["accepted_at"] > done)
        if running is not None:
            return {**(report or {"pairs": []}), **running, "note": NOTE, "how": HOW}
        if failed is not None:
            return {**(report or {"pairs": []}), **failed, "note": NOTE, "how": HOW}
        if report is None:
            return {"status": "none", "pairs": [], "note": NOTE, "how": HOW}
        return report
