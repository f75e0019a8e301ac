"""The course's rules: publishing and editing assignments, the roster and its tokens, submissions (their caps,
the deadline and late cut-off, each handed once to its version's grading run), what a student may see of a
grade (the feedback policy), the counting submission and the grades.

**Graded once, the reference shared.** Each version of an assignment has one *open* grading run
(server/grading/runs.py, `GradeRuns.start(..., open_=True)`): it renders the reference mean as soon as the
version is published, grades the reference scene itself (the instructor's check that it earns full marks,
and the source of the reference image), then takes each submission as one more student of that run. So the
reference is rendered once per version and each noise baseline once per (sampler, spp, light samples) of
the version, whatever the number of submissions; every render is a batch-lane job; and the run's rows
make it durable: a restarted server resumes it. A submission's file is linked into the run's folder, then its
row here and its row in the run (keyed by its own id) are written in one transaction: a full disk keeps
neither (507). A regrade hands rows again (`INSERT OR IGNORE`): handed twice, graded once.

**Time** is `clock()`, the app's `state.clock` (UTC now; tests set it): a submission's time is the clock when
its body was accepted, and the deadline, the late mark and the feedback shown follow it.

**Identity**: a student's token is issued here and kept as its SHA-256, which is exactly the owner that
server/core/security.py derives from a bearer token, so the same token owns the student's workspace jobs.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import secrets
import threading
import uuid
from collections.abc import Callable
from concurrent.futures import TimeoutError
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from datetime import UTC, datetime
from functools import partial
from pathlib import Path

from server.core.errors import Conflict, Forbidden, Invalid, NotFound, TooMany, Unavailable
from server.core.files import write_atomic
from server.core.security import Caller, token_hash
from server.core.settings import Settings
from server.course.people import ROLES, TokenMaker, Who, check_course_id, refuse_ta
from server.course.policy import AssignmentIn, Feedback, Policy, When
from server.course.store import DEFAULT_COURSE, CourseStore
from server.grading.runs import GradeRuns, Handed
from server.jobs.service import Follower, wake_all
from server.jobs.store import JobStore
from tracer.grading import Assignment, AssignmentError, Grader, load_assignment, student_name, tasks
from tracer.tools import spreadsheet

log = logging.getLogger(__name__)

ACTIONS = {"publish": "publish or edit an assignment", "roster": "change the roster or its links",
           "staff": "change the course's staff", "regrade": "regrade", "extend": "grant extensions"}  # fmt: skip
REFERENCE = "reference"  # the reference scene's row in a version's grading run (submission ids are hex)
IMAGE_TESTS = ("flip", "ssim", "psnr", "pixels")
VISIBILITY = {When.now: "visible", When.after_deadline: "after_due_date", When.never: "hidden"}  # Gradescope's
SUFFIX = {"scene": ".json", "png": ".png", "exr": ".exr"}
# whether a caller who is none of a course's staff may act as the admin (the instructor); raises if not. The routes
# hand in server/core/security.check_instructor for their server and their caller's address
Check = Callable[[Caller], object]
CHECK_SECONDS = 30  # a check waits this long for a grading process (they are busy with a deadline's burst)


def not_found(what: str, key: str) -> NotFound:
    return NotFound([{"path": "id", "message": f"no {what} with id '{key[:64]}'"}])


def iso(t: float | None) -> str | None:
    return None if t is None else datetime.fromtimestamp(t, UTC).isoformat().replace("+00:00", "Z")


class Course:
    def __init__(self, settings: Settings, runs: GradeRuns, clock: Callable[[], datetime]):
        self.settings, self.runs, self.clock = settings, runs, clock
        self.store = CourseStore(settings.data_dir, self.now())
        self.tokens = TokenMaker(settings.data_dir / "keys")
        self.root = settings.data_dir / "course"
        self.root.mkdir(parents=True, exist_ok=True)
        self._specs: dict[tuple[str, int], Assignment] = {}  # a version's spec, parsed (versions never change)
        self._followers: dict[str, set[Follower]] = {}  # a submission's event streams, by its id
        self._lock = threading.Lock()
        runs.listeners.append(self._changed)

    def now(self) -> float:
        return self.clock().timestamp()

    # -- publishing ----------------------------------------------------------------------------

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

    def _open_run(self, spec_text: str) -> str:
        spec = json.loads(spec_text)
        handed = []
        if spec.get("reference"):
            scene = json.dumps(spec["reference"]["scene"]).encode()
            handed.append(Handed(REFERENCE, "scene", "reference.json", scene))
        return self.runs.start(spec, handed, open_=True)["id"]

    def publish(self, body: AssignmentIn, cid: str = DEFAULT_COURSE) -> dict:
        """A new assignment of course `cid` (its roster: the course's members enrolled in every assignment)."""
        self.course(cid)
        spec, policy = self._checked(body)
        aid = uuid.uuid4().hex
        run_id = self._open_run(spec)
        try:
            self.store.create(aid, spec, policy, run_id, self.now(), cid)
        except BaseException:  # a full disk: the run ends (its reference is graded), no assignment is left
            self.runs.close(run_id)
            raise
        log.info("assignment %s published (grading run %s)", aid, run_id)
        return self.store.assignment(aid)

    def edit(self, aid: str, body: AssignmentIn, regrade: bool) -> dict:
        """A new version (the earlier ones are kept); `regrade`: every submission graded again under it, as
        rows of its grading run (durable as any)."""
        self.assignment(aid)  # 404 for an unknown one
        spec, policy = self._checked(body)
        run_id = self._open_run(spec)
        try:
            version = self.store.add_version(aid, spec, policy, run_id, self.now())
        except BaseException:
            self.runs.close(run_id)
            raise
        # the old version's run stays open: a submission accepted under it a moment ago is still handed to
        # it and graded (closing it could let its thread end first); an idle open run costs a look a second
        if regrade:
            for sub in self.store.regrade(aid, version, run_id):
                self._hand(sub)
        return self.store.assignment(aid)

    def regrade(self, aid: str) -> dict:
        """Every submission graded again: a new version with the same spec and policy, and its own run (the
        earlier grades stay in their version's run)."""
        a = self.assignment(aid)
        spec = json.dumps(a["spec"])
        run_id = self._open_run(spec)
        try:
            version = self.store.add_version(aid, spec, a["policy"], run_id, self.now())
        except BaseException:
            self.runs.close(run_id)
            raise
        for sub in self.store.regrade(aid, version, run_id):
            self._hand(sub)
        log.info("assignment %s regraded as version %d (grading run %s)", aid, version, run_id)
        return self.store.assignment(aid)

    def assignment(self, aid: str) -> dict:
        a = self.store.assignment(aid) if len(aid) == 32 else None
        if a is None:
            raise not_found("assignment", aid)
        return a

    # -- who asks ------------------------------------------------------------------------------

    def role(self, cid: str, caller: Caller) -> Who | None:
        """The caller in course `cid`: a student of it (their member row; enrolment is the assignment's
        question), one of its staff, or the server's admin; None for anyone else."""
        mine = self.store.token(caller.owner) if caller.owner else None
        if mine is not None and mine["course_id"] == cid:
            if mine["kind"] == "student":
                member = self.store.member(cid, mine["person"])
                if member is not None:
                    return Who(member, "student")
            else:
                staff = self.store.staff_member(cid, mine["person"])
                if staff is not None:
                    return Who(None, staff["role"], staff["person"])
        if caller.instructor:
            return Who(None, "admin")
        return None

    def who(self, aid: str, caller: Caller) -> tuple[dict, Who]:
        """The assignment and the caller: one of its students (by their token), its course's staff, or the
        admin; anyone else gets the 404 of an unknown assignment."""
        a = self.assignment(aid)
        student = self.store.by_token(aid, caller.owner) if caller.owner else None
        if student is not None:
            return a, Who(student, "student")
        who = self.role(a["course_id"], caller)
        if who is None or who.student is not None:  # a member not enrolled in this one: unknown to them
            if caller.instructor:
                return a, Who(None, "admin")
            raise not_found("assignment", aid)
        return a, who

    def staff(self, aid: str, caller: Caller, instructor: Check, action: str = "follow") -> tuple[dict, Who]:
        """The assignment for its course's staff (a TA only for what a TA may do: 403 otherwise); its students
        get the 404 of an unknown id, anyone else what `instructor` says (401 or 403: check_instructor)."""
        a = self.assignment(aid)
        if caller.owner and self.store.by_token(aid, caller.owner) is not None:
            raise not_found("assignment", aid)
        who = self.role(a["course_id"], caller)
        if who is None or who.student is not None:
            instructor(caller)
            who = Who(None, "admin")
        if not who.may(action):
            raise refuse_ta(ACTIONS.get(action, action))
        return a, who

    def course_staff(
        self, cid: str, caller: Caller, instructor: Check, action: str = "follow", hide: bool = True
    ) -> Who:
        """The caller as staff of course `cid` (404 for an unknown course; 403 for a TA where an instructor
        is needed). Anyone else who cannot be the admin gets the same 404 as for an unknown course: no token, a
        student of it, or a good token of another course (course ids are not told); a token known nowhere gets
        what `instructor` says (401, counted against its address, or 403). `hide=False` where the caller named no
        course (POST /api/assignments: the default one): `instructor` answers everyone."""
        self.course(cid)
        who = self.role(cid, caller)
        if who is None or who.student is not None:
            known = caller.owner is None or self.store.roster_kind(caller.owner) is not None
            if hide and not caller.instructor and known:
                raise NotFound([{"path": "course", "message": f"no course with id '{str(cid)[:64]}'"}])
            instructor(caller)
            who = Who(None, "admin")
        if not who.may(action):
            raise refuse_ta(ACTIONS.get(action, action))
        return who

    # -- courses -------------------------------------------------------------------------------

    def course(self, cid: str) -> dict:
        c = self.store.course(cid) if isinstance(cid, str) and len(cid) <= 40 else None
        if c is None:
            raise NotFound([{"path": "course", "message": f"no course with id '{str(cid)[:64]}'"}])
        return c

    def create_course(self, cid: str, name: str) -> dict:
        check_course_id(cid)
        if not self.store.add_course(cid, " ".join(name.split())[:200] or cid, self.now()):
            raise Conflict([{"path": "id", "message": f"there is a course '{cid}' already"}])
        log.info("course %s created", cid)
        return self.store.course(cid)

    def course_view(self, cid: str, who: Who, base: str) -> dict:
        """A course: its assignments (a student: those they are on the roster of, with links), its staff and the
        size of its roster (its staff)."""
        c = self.course(cid)
        out = {"id": c["id"], "name": c["name"], "created_at": iso(c["created_at"]), "assignments": []}
        for aid in self.store.assignments(cid):
            a = self.store.assignment(aid)
            if who.student is not None and self.store.student(aid, who.student["student"]) is None:
                continue
            out["assignments"].append(
                {"id": aid, "name": a["spec"]["name"], "deadline": a["policy"]["deadline"],
                 "version": a["version"], "url": f"/api/assignments/{aid}", "page": f"/assignments/{aid}"}
            )  # fmt: skip
        if who.student is not None:
            s = who.student
            out["you"] = {"id": s["student"], "name": s["name"], "role": "student"}
        else:
            out["you"] = {"role": who.role, "id": who.person}
            out["staff"] = [
                {"id": s["person"], "name": s["name"], "email": s["email"], "role": s["role"]}
                for s in self.store.staff(cid)
            ]
            out["students"] = len(self.store.members(cid))
        return out

    # -- tokens and links ----------------------------------------------------------------------

    def token_of(self, cid: str, kind: str, person: str, gen: int) -> str:
        """Someone's current token (derived: people.py), its hash kept so that it opens their work."""
        token = self.tokens.token(kind, cid, person, gen)
        self.store.keep_token(cid, kind, person, token_hash(token), self.now())
        return token

    def _link(self, base: str, aid: str, token: str) -> str:
        return f"{base.rstrip('/')}/assignments/{aid}#token={token}"

    def course_link(self, base: str, cid: str, token: str, staff: bool = False) -> str:
        page = "course" if staff else f"courses/{cid}"
        return f"{base.rstrip('/')}/{page}#token={token}"

    # -- the roster ----------------------------------------------------------------------------

    def roster(self, aid: str, text: str, base: str) -> list[dict]:
        """The roster CSV (header id,name,email) of one assignment -> each student with their link and token:
        members of the assignment's course (added if new: one identity across the course's assignments),
        enrolled in this assignment. A token is shown again each time (it is derived: the same link)."""
        a = self.assignment(aid)
        rows = parse_roster(text)
        added = set(self.store.add_members(a["course_id"], rows, self.now(), [aid]))
        return [self._student_link(a["course_id"], r, base, aid, r["student"] in added) for r in rows]

    def course_roster(self, cid: str, text: str, base: str) -> list[dict]:
        """The course's roster CSV: each student a member enrolled in every assignment of the course (those
        published later too), with their course link (the page that lists their assignments)."""
        self.course(cid)
        rows = [{**r, "every": 1} for r in parse_roster(text)]
        added = set(self.store.add_members(cid, rows, self.now(), []))
        return [self._student_link(cid, r, base, None, r["student"] in added) for r in rows]

    def _student_link(self, cid: str, r: dict, base: str, aid: str | None, new: bool) -> dict:
        member = self.store.member(cid, r["student"])
        token = self.token_of(cid, "student", member["student"], member["gen"])
        link = self._link(base, aid, token) if aid else self.course_link(base, cid, token)
        out = {"id": member["student"], "name": member["name"], "email": member["email"], "token": token,
               "link": link, "new": new}  # fmt: skip
        if r.get("warning"):  # the roster's row lost characters of its name (parse_roster)
            out["warning"] = r["warning"]
        return out

    def links(self, cid: str, base: str, aid: str | None = None) -> list[dict]:
        """Every student's current link again (of one assignment, or the course's page): nothing changes."""
        return [self._student_link(cid, r, base, aid, False) for r in self._roster(cid, aid)]

    def renew_links(self, cid: str, base: str, jobs: JobStore, aid: str | None = None) -> list[dict]:
        """A new link for every student of the course (or of one assignment's roster), in one request: every
        link sent before stops working, in every assignment of the course; their workspace jobs move."""
        rows = self._roster(cid, aid)
        for r in rows:
            self.renew(cid, "student", r["student"], jobs)
        return [self._student_link(cid, r, base, aid, True) for r in rows]

    def _roster(self, cid: str, aid: str | None) -> list[dict]:
        """One assignment's students, or the course's."""
        return self.store.students(aid) if aid else self.store.members(cid)

    def new_link(self, aid: str, student: str, base: str, jobs: JobStore) -> dict:
        """A fresh token for one student (every old one stops working, in every assignment of the course);
        their workspace jobs move to it."""
        a = self.assignment(aid)
        row = self.store.student(aid, student)
        if row is None:
            raise NotFound([{"path": "student", "message": f"no student '{student[:80]}' on the roster"}])
        token = self.renew(a["course_id"], "student", student, jobs)
        return {"id": student, "name": row["name"], "token": token, "link": self._link(base, aid, token)}

    def renew(self, cid: str, kind: str, person: str, jobs: JobStore) -> str:
        """A new token for someone (every earlier one of theirs stops working); their workspace jobs move to it."""
        old = self.store.token_hashes(cid, kind, person)
        gen = self.store.next_gen(cid, kind, person)
        token = self.token_of(cid, kind, person, gen)
        for h in old:
            jobs.give_owner(h, token_hash(token))
        return token

    def join(self, aid: str, name: str, base: str) -> dict:
        """An open assignment: anyone with its link joins by a name (marked self-declared), a member of its
        course on this assignment's roster only."""
        a = self.assignment(aid)
        if not a["policy"]["open"]:
            raise not_found("assignment", aid)
        shown = " ".join(spreadsheet.clean_name(name)[0].split())  # no control or bidi override (parse_roster)
        sid = f"{student_name(shown)[:60] or 'student'}-{secrets.token_hex(3)}"
        row = {"student": sid, "name": shown, "email": ""}
        most = self.settings.max_joins_per_assignment
        if not self.store.add_joined(aid, a["course_id"], row, self.now(), most):
            message = (
                f"this open assignment already has {most} students who joined by a name, the most it takes "
                "(TRACER_MAX_JOINS_PER_ASSIGNMENT): ask your instructor for a link of the roster"
            )
            raise Forbidden([{"path": "", "message": message}])
        token = self.token_of(a["course_id"], "student", sid, 0)
        return {"id": sid, "name": shown, "token": token, "link": self._link(base, aid, token), "self_declared": True}

    # -- staff ---------------------------------------------------------------------------------

    def add_staff(self, cid: str, person: str, name: str, email: str, role: str, base: str) -> dict:
        self.course(cid)
        if not person or student_name(person) != person or len(person) > 80:
            message = f"{person[:80]!r}: an id is 1 to 80 letters, digits, '.', '_' or '-' (no spaces)"
            raise Invalid([{"path": "id", "message": message}])
        if role not in ROLES:
            raise Invalid([{"path": "role", "message": f"expected one of {', '.join(ROLES)}; got {role!r}"}])
        self.store.add_staff(cid, {"person": person, "name": name or person, "email": email, "role": role}, self.now())
        return self.staff_link(cid, person, base)

    def staff_link(self, cid: str, person: str, base: str) -> dict:
        s = self.store.staff_member(cid, person)
        if s is None:
            raise NotFound([{"path": "staff", "message": f"no staff member '{person[:80]}' in course '{cid}'"}])
        token = self.token_of(cid, "staff", person, s["gen"])
        return {"id": person, "name": s["name"], "email": s["email"], "role": s["role"], "token": token,
                "link": self.course_link(base, cid, token, staff=True)}  # fmt: skip

    def extend(self, aid: str, student: str, deadline: datetime | None) -> dict:
        a = self.assignment(aid)
        if not self.store.extend(aid, student, deadline.timestamp() if deadline else None):
            raise NotFound([{"path": "student", "message": f"no student '{student[:80]}' on the roster"}])
        row = self.store.student(aid, student)
        due, cut = self.deadlines(a, row)
        return {"id": student, "deadline": iso(due), "late_until": iso(cut)}

    # -- deadlines -----------------------------------------------------------------------------

    @staticmethod
    def deadlines(a: dict, student: dict | None) -> tuple[float, float]:
        """(the student's deadline, their late cut-off) as Unix times: an extension moves both by as much."""
        p = a["policy"]
        due = datetime.fromisoformat(p["deadline"]).timestamp()
        cut = datetime.fromisoformat(p["late_until"]).timestamp() if p["late_until"] else due
        if student is not None and student["deadline"] is not None:
            shift = student["deadline"] - due
            due, cut = student["deadline"], max(student["deadline"], cut + shift)
        return due, cut

    def shown(self, when: str, a: dict, who: Who, now: float) -> bool:
        if who.instructor or when == When.now:
            return True
        if when == When.never:
            return False
        return now >= self.deadlines(a, who.student)[1]

    # -- submissions ---------------------------------------------------------------------------

    def submit(self, a: dict, who: Who, kind: str, data: bytes, accepted: float) -> dict:
        """Keep the submission (its file, then its row: acknowledged), then hand it to the grading run."""
        if who.instructor:
            raise Forbidden(
                [
                    {
                        "path": "Authorization",
                        "message": "submissions are a student's: send a student's token (the roster gives each one)",
                    }
                ],
            )
        student = who.student
        due, cut = self.deadlines(a, student)
        if accepted > cut:
            late = f"; late submissions were taken until {iso(cut)}" if cut > due else ""
            message = f"the deadline was {iso(due)}{late}; this submission came at {iso(accepted)}"
            raise Forbidden([{"path": "deadline", "message": message}])
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
                                                    also=partial(self.runs.gs.add_item, a["run_id"], item))  # fmt: skip
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
        return self.submission(a, sid)

    def check(self, a: dict, who: Who, kind: str, data: bytes) -> dict:
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
        keys = report_keys(assignment, kind)
        tests = []
        for key, t in zip(keys, report["tests"], strict=False):
            when = feedback.tests.get(key, feedback.default)
            entry = {"name": t["name"], "test": key, "max_score": t["max_score"], "shown": when}
            if self.shown(when, a, who, now):
                entry.update(
                    score=t["score"], status="passed" if t["score"] >= t["max_score"] else "failed", output=t["output"]
                )
            else:
                entry["hidden"] = f"shown {'after the deadline' if when == When.after_deadline else 'never'}"
            tests.append(entry)
        valid = not report["errors"]
        return {
            "valid": valid,
            "tests": tests,
            "errors": report["errors"],
            "warnings": report["warnings"],
            "image_tests": list(assignment.image_tests()) if valid else [],
            **probes,
        }

    def _check_probes(self, a: dict, who: Who, feedback: Feedback, now: float, path: Path, kind: str) -> dict:
        """An image's probes in the check (docs/own-tracer.md), as the policy shows the error map now: {"probes"},
        {"probes_hidden": when}, or {"probes_pending": why} while the reference is not rendered yet."""
        if not self._map_shown(a, a["version"], who, feedback, now):
            return {"probes_hidden": self._probes_hidden(a, who, feedback)}
        folder = self.runs.folder(a["run_id"]) if a.get("run_id") else None
        mean = next((r for r in self.runs.gs.renders(a["run_id"]) if r["key"] == "mean"), None) if folder else None
        if mean is None or mean["status"] != "done" or not mean.get("job_id"):
            return {"probes_pending": "the reference is still being rendered: the probes come with the check once "
                    "it is done, and with your submission's feedback"}  # fmt: skip
        exr = folder / "renders" / f"{mean['job_id']}.exr"
        found = self.runs.pool.submit(tasks.probe_image, json.dumps(a["spec"]), str(exr), str(path), kind)
        found = found.result(timeout=CHECK_SECONDS)
        return {"probes": found["probes"]} if "probes" in found else {"probes_pending": found["error"]}

    def submissions(self, a: dict, student: str | None = None) -> list[dict]:
        """Submissions (one student's, or all), each `late` by the student's deadline as it is now: an
        extension granted afterwards, or an edit that moves the deadline, takes a late mark (and its penalty)
        away or gives it (the row keeps what was true when the body came)."""
        subs = self.store.submissions(a["id"], student)
        due = {s["student"]: self.deadlines(a, s)[0] for s in self.store.students(a["id"])}
        for sub in subs:
            sub["late"] = int(sub["accepted_at"] > due.get(sub["student"], sub["accepted_at"]))
        return subs

    def submission(self, a: dict, sid: str) -> dict | None:
        sub = self.store.submission(a["id"], sid) if len(sid) == 32 else None
        if sub is not None:
            sub["late"] = int(sub["accepted_at"] > self.deadlines(a, self.store.student(a["id"], sub["student"]))[0])
        return sub

    def _handed(self, sub: dict) -> Handed:
        return Handed(sub["id"], sub["kind"], f"submission{SUFFIX[sub['kind']]}", path=self.root / sub["file"])

    def _hand(self, sub: dict) -> None:
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

    # -- following a submission ---------------------------------------------------------------

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

    # -- what a caller sees --------------------------------------------------------------------

    def spec(self, aid: str, version: int) -> Assignment:
        """A version's spec, parsed once."""
        key = (aid, version)
        if key not in self._specs:
            row = next(v for v in self.store.versions(aid) if v["version"] == version)
            self._specs[key] = load_assignment(row["spec"])[0]
        return self._specs[key]

    def brief(self, a: dict, who: Who, base: str) -> dict:
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
        if who.instructor:
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
            )
        return out

    def view(self, a: dict, sub: dict, who: Who, counting: str | None = None) -> dict:
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
            out["files"] = {name: f"{out['url']}/{name}" for name in self.files(a, sub, who)}
        return out

    def view_one(self, a: dict, sub: dict, who: Who) -> dict:
        """`view` of one submission, with whether it is the one that counts among its student's."""
        c = self.counting(a, self.submissions(a, sub["student"]))
        return self.view(a, sub, who, c["id"] if c else None)

    def files(self, a: dict, sub: dict, who: Who) -> list[str]:
        """The pictures of a graded submission the caller may fetch: its render (their own work); the error
        map and the rejected pixels when no image test is hidden (they show the reference's structure); the
        reference when the policy shows it. The instructor: all of them."""
        if status_of(sub) != "graded":
            return []
        feedback = Feedback.model_validate(a["policy"]["feedback"])
        now = self.now()
        names = ["render.png"]
        if self._map_shown(a, sub["version"], who, feedback, now):
            names += ["error_map.png", "rejected.png"]
        if who.instructor or a["policy"]["show_reference"]:
            names.append("reference.png")
        folder = self.runs.root / sub["run_id"] / "out" / sub["id"]
        return [n for n in names if (folder / n).is_file()]

    def file(self, a: dict, sub: dict, who: Who, name: str) -> Path | None:
        if name not in self.files(a, sub, who):
            return None
        return self.runs.root / sub["run_id"] / "out" / sub["id"] / name

    def _feedback(self, a: dict, sub: dict, report: dict, feedback: Feedback, who: Who, now: float) -> dict:
        keys = report_keys(self.spec(a["id"], sub["version"]), sub["kind"])
        tests, hidden_image = [], False
        for key, t in zip(keys, report.get("tests", []), strict=False):
            when = feedback.tests.get(key, feedback.default)
            entry = {"name": t["name"], "test": key, "max_score": t["max_score"], "shown": when}
            if self.shown(when, a, who, now):
                entry.update(score=t["score"], status=t["status"], output=t["output"])
            else:
                entry["hidden"] = f"shown {'after the deadline' if when == When.after_deadline else 'never'}"
                hidden_image |= key in IMAGE_TESTS
            tests.append(entry)
        out = {"tests": tests, "errors": report.get("errors", []), "warnings": report.get("warnings", [])}
        if not hidden_image and report.get("metrics"):
            out["metrics"] = report["metrics"]
        probes = (report.get("metrics") or {}).get("probes")
        if probes is not None and not hidden_image:  # shown with the error map (docs/own-tracer.md)
            out["probes"] = probes
        elif probes is not None:
            out["probes_hidden"] = self._probes_hidden(a, who, feedback)
        return out

    def _map_shown(self, a: dict, version: int, who: Who, feedback: Feedback, now: float) -> bool:
        """Whether the error map (and the rejected pixels, the probes) is shown to the caller now: every image
        test's feedback shown."""
        tests = self.spec(a["id"], version).image_tests()
        return all(self.shown(feedback.tests.get(k, feedback.default), a, who, now) for k in tests)

    def _probes_hidden(self, a: dict, who: Who, feedback: Feedback) -> str:
        """When the probe pixels appear, for a student to whom the error map is hidden now."""
        tests = self.spec(a["id"], a["version"]).image_tests()
        if any(feedback.tests.get(k, feedback.default) == When.never for k in tests):
            when = "never, for this assignment"
        elif who.student:
            when = f"after your deadline, from {iso(self.deadlines(a, who.student)[1])}"
        else:
            when = "after the deadline"
        return f"the probe pixels are shown with the error map: {when}"

    def counting(self, a: dict, subs: list[dict]) -> dict | None:
        """The submission that is the grade: the last graded one, or the best (by the share of its points
        after the late penalty; the later of two equal ones)."""
        graded = [s for s in subs if status_of(s) == "graded" and s["score"] is not None]
        if not graded:
            return None
        if a["policy"]["counts"] == "last":
            return graded[-1]
        penalty = a["policy"]["late_penalty"]

        def share(s: dict) -> float:
            return s["score"] * (1 - (penalty if s["late"] else 0)) / (s["max_score"] or 1)

        return max(reversed(graded), key=share)

    def class_grades(self, a: dict) -> list[tuple[dict, list[dict], dict | None, float | None]]:
        """Each roster student: (their row, their submissions in order, the counting submission or None, its
        score after the late penalty or None), in the roster's order."""
        subs: dict[str, list[dict]] = {}
        for s in self.submissions(a):
            subs.setdefault(s["student"], []).append(s)
        out = []
        for st in self.store.students(a["id"]):
            mine = subs.get(st["student"], [])
            c = self.counting(a, mine)
            penalty = a["policy"]["late_penalty"] if c is not None and c["late"] else 0.0
            out.append((st, mine, c, None if c is None else c["score"] * (1 - penalty)))
        return out

    def final_grades(self, a: dict) -> list[tuple[dict, dict | None, float | None, int]]:
        """Each roster student: (their row, the counting submission or None, its score after the late
        penalty or None, how many submissions they made), in the roster's order."""
        return [(st, c, score, len(mine)) for st, mine, c, score in self.class_grades(a)]

    def grades_csv(self, a: dict) -> str:
        """One row per roster student: id, name, score (the counting submission's, late penalty applied; empty
        when none was graded), max_score, late, submissions (all they made)."""
        buf = io.StringIO()
        w = spreadsheet.writer(buf, lineterminator="\n")
        w.writerow(["id", "name", "score", "max_score", "late", "submissions"])
        for st, c, score, n in self.final_grades(a):
            if c is None:
                w.writerow([st["student"], st["name"], "", "", "", n])
            else:
                late = "true" if c["late"] else "false"
                w.writerow([st["student"], st["name"], _num(score), _num(c["max_score"]), late, n])
        return buf.getvalue()

    def gradebook_csv(self, a: dict) -> str:
        """The grades as a learning management system imports them (Canvas's gradebook columns: Student, ID,
        SIS User ID, SIS Login ID, Section, then one column for this assignment, and a Points Possible row):
        the roster's id as the SIS User ID, its email as the SIS Login ID; a student with nothing graded has
        an empty cell, which an import leaves as it was. The column has one number of points (the spec's), so
        a score out of another maximum (an image: no requirements) is scaled to it: 3.5 of 7 is 6.5 of 13."""
        spec = self.spec(a["id"], a["version"])
        buf = io.StringIO()
        w = spreadsheet.writer(buf, lineterminator="\n")
        w.writerow(["Student", "ID", "SIS User ID", "SIS Login ID", "Section", f"{spec.name} ({a['id'][:8]})"])
        points = spec.max_score()
        w.writerow(["Points Possible", "", "", "", "", _num(points)])
        for st, c, score, _ in self.final_grades(a):
            scaled = None if c is None else score * points / (c["max_score"] or points)
            w.writerow([st["name"], "", st["student"], st.get("email") or "", "", _num(scaled)])
        return buf.getvalue()

    def gradescope(self, a: dict, sub: dict) -> dict | None:
        """A graded submission as Gradescope's autograder results.json (for an autograder that hands a
        student's work to this service and reports what it says): each test's visibility from the feedback
        policy (now: visible, after the deadline: after_due_date, never: hidden), the score after the late
        penalty, and the whole result's visibility that of the score. None before it is graded."""
        path = self.runs.root / sub["run_id"] / "out" / sub["id"] / "results.json"
        if sub.get("stage") != "graded" or not path.is_file():
            return None
        results = json.loads(path.read_text())
        feedback = Feedback.model_validate(a["policy"]["feedback"])
        keys = report_keys(self.spec(a["id"], sub["version"]), sub["kind"])
        for key, test in zip(keys, results.get("tests", []), strict=False):
            test["visibility"] = VISIBILITY[When(feedback.tests.get(key, feedback.default))]
        results["visibility"] = VISIBILITY[When(feedback.score_when())]
        if sub["late"] and a["policy"]["late_penalty"]:
            penalty = a["policy"]["late_penalty"]
            results["score"] = round(results["score"] * (1 - penalty), 6)
            results["output"] += f"\nlate: {penalty:g} of the points taken off"
        return results

    def reference_png(self, a: dict) -> Path | None:
        """The reference image, once the version's reference is graded (its pictures are written whole by then)."""
        ref = self.runs.gs.item(a["run_id"], REFERENCE)
        path = self.runs.root / a["run_id"] / "out" / REFERENCE / "reference.png"
        return path if ref is not None and ref["stage"] == "graded" and path.is_file() else None


def status_of(sub: dict) -> str:
    """queued (not yet taken up), grading, or the report's: graded, invalid, failed."""
    stage = sub.get("stage")
    if stage is None or stage == "submitted":
        return "queued"
    if stage != "graded":
        return "grading"
    return sub["status"] or "failed"


def _grade(item: dict) -> dict:
    return {
        "status": item["status"] if item["stage"] == "graded" else status_of(item),
        "score": item["score"],
        "max_score": item["max_score"],
    }


def _num(x: float | None) -> str:
    return "" if x is None else f"{round(x, 6):g}"


def test_keys(assignment) -> list[str]:
    """The names a feedback policy may give tests: validity, the requirements', the image tests'."""
    return ["validity", *(r.name for r in assignment.requirements), *assignment.image_tests()]


def report_keys(assignment, kind: str) -> list[str]:
    """The policy's name of each test of a report, in the report's order (an image has no requirements)."""
    requirements = [r.name for r in assignment.requirements] if kind == "scene" else []
    return ["validity", *requirements, *assignment.image_tests()]


def parse_roster(text: str) -> list[dict]:
    """A roster CSV (header: id,name,email) -> rows; 422 naming the line and column of anything wrong."""
    reader = csv.reader(io.StringIO(text.lstrip("\ufeff")))
    try:
        header = next(reader, None)
    except csv.Error as e:
        raise Invalid([{"path": "line 1", "message": f"not CSV: {e}"}]) from None
    if header is None or [h.strip().lower() for h in header] != ["id", "name", "email"]:
        got = ",".join(header or [])[:120]
        raise Invalid([{"path": "line 1", "message": f"expected the header 'id,name,email'; got {got!r}"}])
    rows, seen, errors = [], {}, []
    try:
        for line, fields in enumerate(reader, start=2):
            if not any(f.strip() for f in fields):
                continue
            if len(fields) != 3:
                errors.append(
                    {"path": f"line {line}", "message": f"expected 3 fields (id,name,email); got {len(fields)}"}
                )
                continue
            sid, name, email = (f.strip() for f in fields)
            name, removed = spreadsheet.clean_name(name)  # no control or bidi override into pages and exports
            name = " ".join(name.split()) if removed else name
            if not sid or student_name(sid) != sid or len(sid) > 80:
                errors.append(
                    {
                        "path": f"line {line}.id",
                        "message": f"{sid[:80]!r}: an id is 1 to 80 letters, digits, "
                        "'.', '_' or '-' (no spaces), not starting or ending with '.' or '_'",
                    }
                )
            elif sid in seen:
                errors.append({"path": f"line {line}.id", "message": f"'{sid}' is on line {seen[sid]} too"})
            if not name:
                errors.append({"path": f"line {line}.name", "message": "a name is required"})
            if email and ("@" not in email or len(email) > 254):
                errors.append({"path": f"line {line}.email", "message": f"{email[:80]!r} is not an email address"})
            seen.setdefault(sid, line)
            rows.append({"student": sid, "name": name[:200], "email": email})
            if removed:
                rows[-1]["warning"] = (
                    f"line {line}.name: {removed} control or bidirectional-override character(s) taken out of "
                    f"the name (kept as {name[:200]!r})"
                )
                log.warning("roster %s", rows[-1]["warning"])
    except csv.Error as e:
        errors.append({"path": f"line {reader.line_num}", "message": f"not CSV: {e}"})
    if errors:
        raise Invalid(errors[:20])
    if not rows:
        raise Invalid([{"path": "line 2", "message": "no students under the header"}])
    return rows


def links_csv(students: list[dict]) -> str:
    buf = io.StringIO()
    w = spreadsheet.writer(buf, lineterminator="\n")
    w.writerow(["id", "name", "email", "link"])
    for s in students:
        w.writerow([s["id"], s["name"], s["email"], s["link"] or ""])
    return buf.getvalue()
