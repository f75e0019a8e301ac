"""The roster and its links: a roster CSV read (one assignment's, or the course's), each student's token and link
(derived: the same link each time), new links (the old ones stop working, their workspace jobs move), joining an
open assignment by a name, and extensions.

**Identity**: a student's token is issued here and kept as its SHA-256, which is exactly the owner that
server/core/security.py derives from a bearer token, so the same token owns the student's workspace jobs."""

from __future__ import annotations

import csv
import io
import logging
import secrets
from datetime import datetime

from server.core.errors import Forbidden, Invalid, NotFound
from server.core.roles import Kind
from server.core.security import token_hash
from server.course.base import CourseBase, iso, not_found
from server.course.people import Who
from server.course.schema import MemberRow, StudentRow
from server.jobs.store import JobStore
from tracer.grading import student_name
from tracer.tools import spreadsheet

log = logging.getLogger(__name__)


class Roster(CourseBase):
    """The roster, tokens and links, joins and extensions (mixed into server/course/service.Course)."""

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

    def roster(self, aid: str, text: str, base: str, who: Who | None = None) -> list[dict]:
        """The roster CSV (header id,name,email) of one assignment -> each student with their link and token:
        members of the assignment's course (added if new: one identity across the course's assignments),
        enrolled in this assignment. A token is shown again each time (it is derived: the same link)."""
        a = self.assignment(aid)
        rows = parse_roster(text)
        added = set(self.store.add_members(a["course_id"], rows, self.now(), [aid], self.by(who, "roster CSV")))
        return [self._student_link(a["course_id"], r, base, aid, r["student"] in added) for r in rows]

    def course_roster(self, cid: str, text: str, base: str, who: Who | None = None) -> list[dict]:
        """The course's roster CSV: each student a member enrolled in every assignment of the course (those
        published later too), with their course link (the page that lists their assignments)."""
        self.course(cid)
        rows = [{**r, "every": 1} for r in parse_roster(text)]
        added = set(self.store.add_members(cid, rows, self.now(), [], self.by(who, "the course's roster CSV")))
        return [self._student_link(cid, r, base, None, r["student"] in added) for r in rows]

    def _student_link(self, cid: str, r: dict | StudentRow | MemberRow, base: str, aid: str | None, new: bool) -> dict:
        member = self.store.member(cid, r["student"])
        assert member is not None  # on the roster: added before its link is made
        token = self.token_of(cid, Kind.STUDENT, member["student"], member["gen"])
        link = self._link(base, aid, token) if aid else self.course_link(base, cid, token)
        out = {"id": member["student"], "name": member["name"], "email": member["email"], "token": token,
               "link": link, "new": new}  # fmt: skip
        if warning := r.get("warning"):  # the roster's row lost characters of its name (parse_roster)
            out["warning"] = warning
        return out

    def links(self, cid: str, base: str, aid: str | None = None) -> list[dict]:
        """Every student's current link again (of one assignment, or the course's page): nothing changes."""
        return [self._student_link(cid, r, base, aid, False) for r in self._roster(cid, aid)]

    def renew_links(
        self, cid: str, base: str, jobs: JobStore, aid: str | None = None, who: Who | None = None
    ) -> list[dict]:
        """A new link for every student of the course (or of one assignment's roster), in one request: every
        link sent before stops working, in every assignment of the course; their workspace jobs move."""
        rows = self._roster(cid, aid)
        for r in rows:
            self.renew(cid, Kind.STUDENT, r["student"], jobs, who, "every link re-issued")
        return [self._student_link(cid, r, base, aid, True) for r in rows]

    def _roster(self, cid: str, aid: str | None) -> list[StudentRow] | list[MemberRow]:
        """One assignment's students, or the course's."""
        return self.store.students(aid) if aid else self.store.members(cid)

    def new_link(self, aid: str, student: str, base: str, jobs: JobStore, who: Who | None = None) -> dict:
        """A fresh token for one student (every old one stops working, in every assignment of the course);
        their workspace jobs move to it."""
        a = self.assignment(aid)
        row = self.store.student(aid, student)
        if row is None:
            raise NotFound([{"path": "student", "message": f"no student '{student[:80]}' on the roster"}])
        token = self.renew(a["course_id"], Kind.STUDENT, student, jobs, who, "a new link")
        return {"id": student, "name": row["name"], "token": token, "link": self._link(base, aid, token)}

    def renew(self, cid: str, kind: str, person: str, jobs: JobStore, who: Who | None = None, why: str = "") -> str:
        """A new token for someone (every earlier one of theirs stops working); their workspace jobs move to it.
        A `link.renew` audit event (the generations, never a token)."""
        old = self.store.token_hashes(cid, kind, person)
        gen = self.store.next_gen(cid, kind, person, self.by(who, why))
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
        if not self.store.add_joined(aid, a["course_id"], row, self.now(), most, self.by(f"student:{sid}", "joined")):
            message = (
                f"this open assignment already has {most} students who joined by a name, the most it takes "
                "(TRACER_MAX_JOINS_PER_ASSIGNMENT): ask your instructor for a link of the roster"
            )
            raise Forbidden([{"path": "", "message": message}])
        token = self.token_of(a["course_id"], Kind.STUDENT, sid, 0)
        return {"id": sid, "name": shown, "token": token, "link": self._link(base, aid, token), "self_declared": True}

    def extend(self, aid: str, student: str, deadline: datetime | None, who: Who | None = None, why: str = "") -> dict:
        """A student's own deadline (None: the assignment's), the grant kept in its history (who, when, before,
        after, why: `extension_history`, the student's detail on the dashboard); an `extension` audit event."""
        a = self.assignment(aid)
        by = (who.person or str(who.role)) if who is not None else ""
        if not self.store.extend(
            aid, student, deadline.timestamp() if deadline else None, by, why, self.now(), self.by(who, why)
        ):
            raise NotFound([{"path": "student", "message": f"no student '{student[:80]}' on the roster"}])
        row = self.store.student(aid, student)
        due, cut = self.deadlines(a, row)
        return {"id": student, "deadline": iso(due), "late_until": iso(cut)}

    def remove_member(self, cid: str, student: str, who: Who | None = None, why: str = "") -> None:
        """A student off the course's rosters (404 if not on it); a `student.remove` audit event."""
        if not self.store.remove_member(cid, student, self.by(who, why)):
            raise NotFound([{"path": "student", "message": f"no student '{student[:80]}' in course '{cid}'"}])


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
