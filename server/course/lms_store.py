"""The course's LMS tables beside the course's own (docs/lti.md): the LMS courses (contexts) linked to courses, the
resource links and their assignments and AGS line items, the picker's one-time forms, and the scores to send back
(durable rows: pending, sent, superseded), read by server/course/lms.py and server/course/lms_poster.py."""

from __future__ import annotations

import secrets
from typing import TypedDict, cast

from server.core.db import Tables

SCHEMA = """
CREATE TABLE IF NOT EXISTS course_lti_contexts (
    platform_id TEXT NOT NULL,            -- server/lti's platform row
    context_id TEXT NOT NULL,             -- the LMS course's id
    course_id TEXT NOT NULL,
    title TEXT NOT NULL DEFAULT '',
    memberships_url TEXT,                 -- its NRPS endpoint, from the latest launch that had one
    synced_at REAL,                       -- the last roster read from it
    created_at REAL NOT NULL,
    PRIMARY KEY (platform_id, context_id)
);
CREATE TABLE IF NOT EXISTS course_lti_links (
    platform_id TEXT NOT NULL,
    resource_link_id TEXT NOT NULL,
    assignment_id TEXT,                   -- NULL until an instructor picks one
    lineitem TEXT,                        -- its AGS line item URL (grades go there)
    course_id TEXT NOT NULL,
    created_at REAL NOT NULL,
    PRIMARY KEY (platform_id, resource_link_id)
);
CREATE TABLE IF NOT EXISTS course_lti_picks (
    id TEXT PRIMARY KEY,                  -- a one-time secret in the picker's form
    platform_id TEXT NOT NULL,
    deployment_id TEXT NOT NULL,
    course_id TEXT NOT NULL,
    settings TEXT NOT NULL,               -- the deep_linking_settings claim (JSON); '' for a link to bind
    resource_link_id TEXT,                -- a link to bind to the picked assignment (no deep linking)
    expires REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS course_lti_scores (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    platform_id TEXT NOT NULL,
    lineitem TEXT NOT NULL,
    user_id TEXT NOT NULL,                -- the LMS's sub
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,
    score_given REAL NOT NULL,
    score_max REAL NOT NULL,
    timestamp REAL NOT NULL,              -- the score's time (strictly increasing per line item and user)
    state TEXT NOT NULL,                  -- pending, sent, superseded (a newer score replaced it unsent), failed
                                          -- (the LMS refused it for good: not tried again until sent again)
    tries INTEGER NOT NULL DEFAULT 0,
    next_try REAL NOT NULL,
    error TEXT,
    created_at REAL NOT NULL,
    sent_at REAL,
    status INTEGER,                       -- the LMS's HTTP status when it refused the score for good
    comment TEXT                          -- the score's comment for the student (AGS `comment`), if any
);
CREATE INDEX IF NOT EXISTS course_lti_scores_due ON course_lti_scores (state, next_try);
CREATE INDEX IF NOT EXISTS course_lti_scores_user ON course_lti_scores (lineitem, user_id, id);
"""


class LtiContextRow(TypedDict):
    """A row of `course_lti_contexts`: an LMS course linked to a course (LmsStore.context, .contexts)."""

    platform_id: str
    context_id: str
    course_id: str
    title: str
    memberships_url: str | None
    synced_at: float | None
    created_at: float


class LtiLinkRow(TypedDict):
    """A row of `course_lti_links`: a resource link, its assignment and its AGS line item (LmsStore.link, .links)."""

    platform_id: str
    resource_link_id: str
    assignment_id: str | None  # None until an instructor picks one
    lineitem: str | None
    course_id: str
    created_at: float


class LtiPickRow(TypedDict):
    """A row of `course_lti_picks`: a picker's one-time form, as LmsStore.take_pick returns it."""

    id: str
    platform_id: str
    deployment_id: str
    course_id: str
    settings: str  # the deep_linking_settings claim (JSON); '' for a link to bind
    resource_link_id: str | None
    expires: float


class LtiScoreRow(TypedDict):
    """A row of `course_lti_scores`: a score to send back (LmsStore.last_score, .due): what the poster posts."""

    id: int
    platform_id: str
    lineitem: str
    user_id: str  # the LMS's sub
    assignment_id: str
    student: str
    score_given: float
    score_max: float
    timestamp: float
    state: str  # pending, sent, superseded, failed
    tries: int
    next_try: float
    error: str | None
    created_at: float
    sent_at: float | None
    status: int | None  # the LMS's HTTP status when it refused the score for good
    comment: str | None


class RefusedScore(TypedDict):
    """A score the LMS refused for good, as LmsStore.refusals returns it (the dashboard's `refused`): some of its
    row's columns, `next_try` as `at` (when it was refused)."""

    id: int
    student: str
    user_id: str
    score_given: float
    score_max: float
    status: int | None
    error: str | None
    at: float


class LmsStore(Tables):
    def __init__(self, data_dir):
        super().__init__(data_dir, SCHEMA)

    def context(self, platform_id: str, context_id: str) -> LtiContextRow | None:
        row = self.db.execute(
            "SELECT * FROM course_lti_contexts WHERE platform_id = ? AND context_id = ?", (platform_id, context_id)
        ).fetchone()
        return cast(LtiContextRow, dict(row)) if row else None

    def contexts(self, course_id: str) -> list[LtiContextRow]:
        rows = self.db.execute("SELECT * FROM course_lti_contexts WHERE course_id = ?", (course_id,))
        return [cast(LtiContextRow, dict(r)) for r in rows]

    def link_context(self, platform_id: str, context_id: str, course_id: str, title: str, now: float) -> None:
        self.db.execute(
            "INSERT INTO course_lti_contexts (platform_id, context_id, course_id, title, created_at)"
            " VALUES (?, ?, ?, ?, ?) ON CONFLICT (platform_id, context_id)"
            " DO UPDATE SET course_id = excluded.course_id",
            (platform_id, context_id, course_id, title, now),
        )

    def set_memberships(self, platform_id: str, context_id: str, url: str | None, synced_at: float | None) -> None:
        if url is not None:
            self.db.execute(
                "UPDATE course_lti_contexts SET memberships_url = ? WHERE platform_id = ? AND context_id = ?",
                (url, platform_id, context_id),
            )
        if synced_at is not None:
            self.db.execute(
                "UPDATE course_lti_contexts SET synced_at = ? WHERE platform_id = ? AND context_id = ?",
                (synced_at, platform_id, context_id),
            )

    def link(self, platform_id: str, link_id: str) -> LtiLinkRow | None:
        row = self.db.execute(
            "SELECT * FROM course_lti_links WHERE platform_id = ? AND resource_link_id = ?", (platform_id, link_id)
        ).fetchone()
        return cast(LtiLinkRow, dict(row)) if row else None

    def keep_link(self, platform_id, link_id, course_id, aid, lineitem, now) -> None:
        self.db.execute(
            "INSERT INTO course_lti_links (platform_id, resource_link_id, assignment_id, lineitem, course_id,"
            " created_at) VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT (platform_id, resource_link_id) DO UPDATE SET"
            " assignment_id = COALESCE(excluded.assignment_id, assignment_id),"
            " lineitem = COALESCE(excluded.lineitem, lineitem)",
            (platform_id, link_id, aid, lineitem, course_id, now),
        )

    def links(self, aid: str) -> list[LtiLinkRow]:
        rows = self.db.execute("SELECT * FROM course_lti_links WHERE assignment_id = ?", (aid,))
        return [cast(LtiLinkRow, dict(r)) for r in rows]

    def linked_assignments(self) -> list[str]:
        rows = self.db.execute(
            "SELECT DISTINCT assignment_id FROM course_lti_links"
            " WHERE assignment_id IS NOT NULL AND lineitem IS NOT NULL"
        )
        return [r[0] for r in rows]

    def new_pick(self, row: dict) -> str:
        pid = secrets.token_urlsafe(24)
        self.db.execute(
            "INSERT INTO course_lti_picks (id, platform_id, deployment_id, course_id, settings, resource_link_id,"
            " expires) VALUES (?, ?, ?, ?, ?, ?, ?)",
            (pid, row["platform_id"], row["deployment_id"], row["course_id"], row["settings"],
             row.get("resource_link_id"), row["expires"]),
        )  # fmt: skip
        return pid

    def take_pick(self, pid: str, now: float) -> LtiPickRow | None:
        with self._tx() as db:
            row = db.execute("SELECT * FROM course_lti_picks WHERE id = ?", (pid,)).fetchone()
            db.execute("DELETE FROM course_lti_picks WHERE id = ? OR expires < ?", (pid, now))
        return cast(LtiPickRow, dict(row)) if row and row["expires"] >= now else None

    # -- scores --------------------------------------------------------------------------------

    def last_score(self, lineitem: str, user_id: str) -> LtiScoreRow | None:
        row = self.db.execute(
            "SELECT * FROM course_lti_scores WHERE lineitem = ? AND user_id = ? AND state != 'superseded'"
            " ORDER BY id DESC LIMIT 1",
            (lineitem, user_id),
        ).fetchone()
        return cast(LtiScoreRow, dict(row)) if row else None

    def add_score(self, row: dict, now: float) -> bool:
        """Keep a score to post (`comment`: optional, sent as AGS's comment), unless the latest one for its line
        item and user has the same numbers and comment; an unsent older one (pending, or failed) is superseded.
        Its timestamp comes after every earlier one's. True if kept."""
        with self._tx() as db:
            last = db.execute(
                "SELECT * FROM course_lti_scores WHERE lineitem = ? AND user_id = ? ORDER BY id DESC LIMIT 1",
                (row["lineitem"], row["user_id"]),
            ).fetchone()
            live = db.execute(
                "SELECT score_given, score_max, comment FROM course_lti_scores WHERE lineitem = ? AND user_id = ?"
                " AND state != 'superseded' ORDER BY id DESC LIMIT 1",
                (row["lineitem"], row["user_id"]),
            ).fetchone()
            if live is not None and tuple(live) == (row["score_given"], row["score_max"], row.get("comment") or None):
                return False
            stamp = max(now, last["timestamp"] + 0.001) if last is not None else now
            db.execute(
                "UPDATE course_lti_scores SET state = 'superseded' WHERE lineitem = ? AND user_id = ?"
                " AND state IN ('pending', 'failed')",
                (row["lineitem"], row["user_id"]),
            )
            db.execute(
                "INSERT INTO course_lti_scores (platform_id, lineitem, user_id, assignment_id, student, score_given,"
                " score_max, timestamp, state, next_try, created_at, comment)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?, 'pending', ?, ?, ?)",
                (row["platform_id"], row["lineitem"], row["user_id"], row["assignment_id"], row["student"],
                 row["score_given"], row["score_max"], stamp, now, now, row.get("comment") or None),
            )  # fmt: skip
        return True

    def due(self, now: float, limit: int) -> list[LtiScoreRow]:
        rows = self.db.execute(
            "SELECT * FROM course_lti_scores WHERE state = 'pending' AND next_try <= ? ORDER BY id LIMIT ?",
            (now, limit),
        )
        return [cast(LtiScoreRow, dict(r)) for r in rows]

    def sent(self, sid: int, now: float) -> None:
        self.db.execute(
            "UPDATE course_lti_scores SET state = 'sent', sent_at = ?, error = NULL WHERE id = ? AND state = 'pending'",
            (now, sid),
        )

    def failed(self, sid: int, error: str, next_try: float) -> None:
        self.db.execute(
            "UPDATE course_lti_scores SET tries = tries + 1, error = ?, next_try = ? WHERE id = ?",
            (error[:500], next_try, sid),
        )

    def refused(self, sid: int, status: int, error: str, now: float) -> None:
        """The LMS refused the score for good (a 4xx other than 401 and 429): `failed`, with its status and why;
        not tried again until staff send it again (`send_again`)."""
        self.db.execute(
            "UPDATE course_lti_scores SET state = 'failed', tries = tries + 1, status = ?, error = ?, next_try = ?"
            " WHERE id = ? AND state = 'pending'",
            (status, error[:500], now, sid),
        )

    def send_again(self, aid: str, now: float, sid: int | None = None) -> int:
        """The assignment's failed scores (or the one `sid`) pending again, to be posted at once; a newer score
        of the same line item and user already kept stays (an older one is not sent over it). How many."""
        one = " AND id = ?" if sid is not None else ""
        cur = self.db.execute(
            "UPDATE course_lti_scores SET state = 'pending', tries = 0, next_try = ?, status = NULL, error = NULL"
            " WHERE assignment_id = ? AND state = 'failed'" + one + " AND NOT EXISTS (SELECT 1 FROM"
            " course_lti_scores n WHERE n.lineitem = course_lti_scores.lineitem AND n.user_id ="
            " course_lti_scores.user_id AND n.id > course_lti_scores.id AND n.state != 'superseded')",
            (now, aid, sid) if sid is not None else (now, aid),
        )
        return cur.rowcount

    def refusals(self, aid: str, limit: int = 50) -> list[RefusedScore]:
        """The assignment's scores the LMS refused for good, newest first: who, the score, the status and why."""
        rows = self.db.execute(
            "SELECT id, student, user_id, score_given, score_max, status, error, next_try AS at FROM"
            " course_lti_scores WHERE assignment_id = ? AND state = 'failed' ORDER BY id DESC LIMIT ?",
            (aid, limit),
        )
        return [cast(RefusedScore, dict(r)) for r in rows]

    def scores(self, aid: str) -> dict:
        """What the dashboard says of the grades sent back: counts by state, the latest error of a score that
        waits, and the scores the LMS refused for good (`refused`: who, status, why)."""
        counts = dict(
            self.db.execute(
                "SELECT state, COUNT(*) FROM course_lti_scores WHERE assignment_id = ? AND state != 'superseded'"
                " GROUP BY state",
                (aid,),
            ).fetchall()
        )
        err = self.db.execute(
            "SELECT error, next_try FROM course_lti_scores WHERE assignment_id = ? AND state = 'pending'"
            " AND error IS NOT NULL ORDER BY id DESC LIMIT 1",
            (aid,),
        ).fetchone()
        return {"pending": counts.get("pending", 0), "sent": counts.get("sent", 0), "failed": counts.get("failed", 0),
                "error": err[0] if err else None, "next_try": err[1] if err else None,
                "refused": self.refusals(aid)}  # fmt: skip
