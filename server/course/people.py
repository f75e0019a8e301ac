"""Who is who in a course: the server's admin, a course's staff (instructors and TAs), its students.

**Roles.** The server admin is the holder of TRACER_INSTRUCTOR_TOKEN (on a loopback-only server without it,
everyone, as before courses): they create courses and staff, and may do anything in any course. A course's
*instructor* may do everything in it (publish and edit assignments, the roster, staff, links, grades); a *TA*
follows the class (dashboards, a student's history, grades), grants extensions and regrades, but may not
publish, edit, change the roster or the staff. A *student* is a member of the course's roster.

**Tokens.** Every token that names someone in a course is derived, never drawn and kept: an HMAC of
(kind, course, person, generation) keyed by the data directory's secret (DATA/keys/tokens.key, made on first
start, 0600). The store keeps only its SHA-256 (`course_tokens`), which is also the owner of the person's
workspace jobs (server/core/security.py). So the same student gets the same token from a roster link, a
re-download of the links and every launch from their LMS, and their "my jobs" follow them; a new link bumps
the generation, and every earlier token of theirs stops working."""

from __future__ import annotations

import base64
import hashlib
import hmac
import os
import re
import secrets
from dataclasses import dataclass
from pathlib import Path

from server.core.errors import Forbidden, Invalid
from server.core.roles import STAFF, Role
from server.course.schema import MemberRow, StudentRow

ROLES = STAFF  # a course's staff (server/core/roles.py)
COURSE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,39}")
COURSE_ID_WORDS = "1 to 40 letters, digits, '-' or '_', starting with a letter or digit"


@dataclass(frozen=True)
class Who:
    """The caller as an assignment sees them: a student of its roster (`student`, their roster row), or staff:
    the server's admin, or one of the course's instructors or TAs (`role`). As a course sees them (Courses.role),
    a student is their member row."""

    student: StudentRow | MemberRow | None = None
    role: Role = Role.INSTRUCTOR  # admin, instructor, ta, or student
    person: str | None = None  # a staff member's id in the course (None: the admin)

    @property
    def instructor(self) -> bool:
        """Staff of the course: sees every student's work (a TA too; what a TA may change is `may`)."""
        return self.student is None

    def may(self, action: str) -> bool:
        """May this caller `action` ("publish", "roster", "staff": an instructor's; "follow", "extend",
        "regrade", "grade" (manual items): a TA's too)?"""
        if self.student is not None:
            return False
        if self.role == Role.TA:
            return action in ("follow", "extend", "regrade", "grade")
        return True


def refuse_ta(action: str) -> Forbidden:
    return Forbidden(
        [
            {
                "path": "role",
                "message": f"a TA may not {action}: the course's instructors may (a TA follows the class, "
                "grants extensions and regrades)",
            }
        ],
    )


def check_course_id(cid: str, path: str = "id") -> str:
    if not COURSE_ID.fullmatch(cid or ""):
        raise Invalid([{"path": path, "message": f"{(cid or '')[:60]!r}: a course id is {COURSE_ID_WORDS}"}])
    return cid


class TokenMaker:
    """Tokens derived from the data directory's secret: `token(kind, course, person, gen)`."""

    def __init__(self, folder: Path):
        path = Path(folder) / "tokens.key"
        if not path.is_file():
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".tokens.key.{os.getpid()}")
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(fd, "wb") as f:
                f.write(secrets.token_bytes(32))
                f.flush()
                os.fsync(f.fileno())
            try:
                os.link(tmp, path)  # the first of two starting processes wins; both then read the same secret
            except FileExistsError:
                pass
            finally:
                tmp.unlink(missing_ok=True)
        self._key = path.read_bytes()
        if len(self._key) < 32:
            raise RuntimeError(f"{path} holds {len(self._key)} bytes; expected 32 (remove it to make a new one)")

    def token(self, kind: str, course: str, person: str, gen: int) -> str:
        msg = f"{kind}\0{course}\0{person}\0{gen}".encode()
        return base64.urlsafe_b64encode(hmac.new(self._key, msg, hashlib.sha256).digest()).decode().rstrip("=")
