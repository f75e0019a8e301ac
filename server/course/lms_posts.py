"""The grades going back to the LMSs, counted over every assignment (the status page, docs/service.md): the rows of
`course_lti_scores` (server/course/lms.py keeps and posts them) waiting to be posted, those of them whose last post
failed, and those sent; the latest failure's message, platform and next try, and the oldest waiting row's age."""

from __future__ import annotations

from datetime import UTC, datetime

from server.course.lms_store import LmsStore


def _iso(t: float | None) -> str | None:
    return datetime.fromtimestamp(t, UTC).isoformat() if t is not None else None


def posts(store: LmsStore, now: datetime) -> dict:
    """`pending` (waiting to be posted, failed ones included), `failed` (waiting after a failed post), `sent`;
    `refused` (refused by the LMS for good: not tried again until staff send them again);
    `last_error` ({message, platform_id, tries, next_try}) of the latest failed one; `oldest_pending_seconds`."""
    db = store.db
    counts = dict(db.execute("SELECT state, COUNT(*) FROM course_lti_scores GROUP BY state").fetchall())
    failed = db.execute(
        "SELECT COUNT(*) FROM course_lti_scores WHERE state = 'pending' AND error IS NOT NULL"
    ).fetchone()[0]
    last = db.execute(
        "SELECT error, platform_id, tries, next_try FROM course_lti_scores WHERE state = 'pending'"
        " AND error IS NOT NULL ORDER BY id DESC LIMIT 1"
    ).fetchone()
    oldest = db.execute("SELECT MIN(created_at) FROM course_lti_scores WHERE state = 'pending'").fetchone()[0]
    return {
        "pending": counts.get("pending", 0),
        "failed": failed,
        "sent": counts.get("sent", 0),
        "refused": counts.get("failed", 0),
        "last_error": {"message": last[0], "platform_id": last[1], "tries": last[2], "next_try": _iso(last[3])}
        if last
        else None,
        "oldest_pending_seconds": max(0.0, now.timestamp() - oldest) if oldest is not None else None,
    }
