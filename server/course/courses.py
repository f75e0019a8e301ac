"""Courses and their staff, and who asks: a course made, its view, its staff added and their links; the caller as
a student of an assignment, one of the course's staff (a TA only for what a TA may do), or the server's admin."""

from __future__ import annotations

import logging
from collections.abc import Callable

from server.core.errors import Conflict, Invalid, NotFound
from server.core.roles import Kind, Role
from server.core.security import Caller
from server.course.base import CourseBase, iso, not_found
from server.course.people import ROLES, Who, check_course_id, refuse_ta
from server.course.schema import AssignmentRow, CourseRow
from tracer.grading import student_name

log = logging.getLogger(__name__)

ACTIONS = {"publish": "publish or edit an assignment", "roster": "change the roster or its links",
           "staff": "change the course's staff", "regrade": "regrade", "extend": "grant extensions",
           "release": "assign graders, switch anonymous grading or release manual grades"}  # fmt: skip
# whether a caller who is none of a course's staff may act as the admin (the instructor); raises if not. The routes
# hand in server/core/security.check_instructor for their server and their caller's address
Check = Callable[[Caller], object]


class Courses(CourseBase):
    """Courses, staff and who asks (mixed into server/course/service.Course)."""

    def role(self, cid: str, caller: Caller) -> Who | None:
        """The caller in course `cid`: a student of it (their member row; enrolment is the assignment's
        question), one of its staff, or the server's admin; None for anyone else."""
        mine = self.store.token(caller.owner) if caller.owner else None
        if mine is not None and mine["course_id"] == cid:
            if mine["kind"] == Kind.STUDENT:
                member = self.store.member(cid, mine["person"])
                if member is not None:
                    return Who(member, Role.STUDENT)
            else:
                staff = self.store.staff_member(cid, mine["person"])
                if staff is not None:
                    return Who(None, Role(staff["role"]), staff["person"])
        if caller.instructor:
            return Who(None, Role.ADMIN)
        return None

    def who(self, aid: str, caller: Caller) -> tuple[AssignmentRow, Who]:
        """The assignment and the caller: one of its students (by their token), its course's staff, or the
        admin; anyone else gets the 404 of an unknown assignment."""
        a = self.assignment(aid)
        student = self.store.by_token(aid, caller.owner) if caller.owner else None
        if student is not None:
            return a, Who(student, Role.STUDENT)
        who = self.role(a["course_id"], caller)
        if who is None or who.student is not None:  # a member not enrolled in this one: unknown to them
            if caller.instructor:
                return a, Who(None, Role.ADMIN)
            raise not_found("assignment", aid)
        return a, who

    def staff(self, aid: str, caller: Caller, instructor: Check, action: str = "follow") -> tuple[AssignmentRow, Who]:
        """The assignment for its course's staff (a TA only for what a TA may do: 403 otherwise); its students
        get the 404 of an unknown id, anyone else what `instructor` says (401 or 403: check_instructor)."""
        a = self.assignment(aid)
        if caller.owner and self.store.by_token(aid, caller.owner) is not None:
            raise not_found("assignment", aid)
        who = self.role(a["course_id"], caller)
        if who is None or who.student is not None:
            instructor(caller)
            who = Who(None, Role.ADMIN)
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
            who = Who(None, Role.ADMIN)
        if not who.may(action):
            raise refuse_ta(ACTIONS.get(action, action))
        return who

    def create_course(self, cid: str, name: str) -> CourseRow:
        check_course_id(cid)
        if not self.store.add_course(cid, " ".join(name.split())[:200] or cid, self.now()):
            raise Conflict([{"path": "id", "message": f"there is a course '{cid}' already"}])
        log.info("course %s created", cid)
        return self.course(cid)

    def course_view(self, cid: str, who: Who, base: str) -> dict:
        """A course: its assignments (a student: those they are on the roster of, with links), its staff and the
        size of its roster (its staff)."""
        c = self.course(cid)
        out = {"id": c["id"], "name": c["name"], "created_at": iso(c["created_at"]), "assignments": [],
               "late_tokens": c["late_tokens"]}  # fmt: skip
        for aid in self.store.assignments(cid):
            a = self.store.assignment(aid)
            if a is None:  # (none: the course's ids are its assignments')
                continue
            if who.student is not None and self.store.student(aid, who.student["student"]) is None:
                continue
            out["assignments"].append(
                {"id": aid, "name": a["spec"]["name"], "deadline": a["policy"]["deadline"],
                 "version": a["version"], "url": f"/api/assignments/{aid}", "page": f"/assignments/{aid}"}
            )  # fmt: skip
        if who.student is not None:
            s = who.student
            out["you"] = {"id": s["student"], "name": s["name"], "role": Role.STUDENT}
        else:
            out["you"] = {"role": who.role, "id": who.person}
            out["staff"] = [
                {"id": s["person"], "name": s["name"], "email": s["email"], "role": s["role"]}
                for s in self.store.staff(cid)
            ]
            out["students"] = len(self.store.members(cid))
        return out

    def add_staff(
        self, cid: str, person: str, name: str, email: str, role: str, base: str, who: Who | None = None
    ) -> dict:
        """A staff member added (or their name, email and role changed): `staff.add` (`staff.change`) audited."""
        self.course(cid)
        if not person or student_name(person) != person or len(person) > 80:
            message = f"{person[:80]!r}: an id is 1 to 80 letters, digits, '.', '_' or '-' (no spaces)"
            raise Invalid([{"path": "id", "message": message}])
        if role not in ROLES:
            raise Invalid([{"path": "role", "message": f"expected one of {', '.join(ROLES)}; got {role!r}"}])
        row = {"person": person, "name": name or person, "email": email, "role": role}
        self.store.add_staff(cid, row, self.now(), self.by(who))
        return self.staff_link(cid, person, base)

    def remove_staff(self, cid: str, person: str, who: Who | None = None) -> None:
        """A staff member removed (404 if none); their token stops working; `staff.remove` audited."""
        if not self.store.remove_staff(cid, person, self.by(who)):
            raise NotFound([{"path": "staff", "message": f"no staff member '{person[:80]}' in course '{cid}'"}])

    def staff_link(self, cid: str, person: str, base: str) -> dict:
        s = self.store.staff_member(cid, person)
        if s is None:
            raise NotFound([{"path": "staff", "message": f"no staff member '{person[:80]}' in course '{cid}'"}])
        token = self.token_of(cid, Kind.STAFF, person, s["gen"])
        return {"id": person, "name": s["name"], "email": s["email"], "role": s["role"], "token": token,
                "link": self.course_link(base, cid, token, staff=True)}  # fmt: skip
