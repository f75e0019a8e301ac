"""Grades back to the LMS (Assignment and Grade Services, docs/lti.md), as rows first (`course_lti_scores`,
durable): when a linked student's counting grade changes and the policy shows the score to them (now, or after
their cut-off), a row with the score is kept, then posted by the poster thread; a platform that is down leaves the
row pending, tried again later with a growing wait (nothing is lost across restarts); the dashboard counts what is
pending. A score the LMS refuses for good (an HTTP 4xx other than 401 and 429: the same post would be refused
again) is not tried again: its row is `failed` with the LMS's status and message, shown on the dashboard, until
staff send it again (POST /api/assignments/{aid}/lms/send-again). Timestamps are strictly increasing per user and
line item, as the AGS specification requires."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from datetime import UTC, datetime

from server.course.lms_store import LmsStore, LtiScoreRow
from server.course.policy import Feedback, When
from server.course.service import Course
from server.lti.services import ServiceError
from server.lti.services import score as score_json
from server.lti.store import PlatformRow

log = logging.getLogger(__name__)

RETRY_FIRST, RETRY_MAX = 30.0, 3600.0  # seconds: the wait after a failed post doubles from the first to the most
POST_BATCH = 50  # scores posted per round of the poster
SWEEP_SECONDS = 60.0  # how often the poster looks for scores released by a deadline


def for_good(e: Exception) -> int | None:
    """The HTTP status of a refusal the same post would meet again (a 4xx other than 401, the token, and 429, too
    many calls): None for a failure worth trying again (no answer, a 5xx, 401, 429, anything else)."""
    status = e.status if isinstance(e, ServiceError) else 0
    return status if 400 <= status < 500 and status not in (401, 429) else None


class Poster:
    """The poster thread of the course's LMS side (server/course/lms.Lms holds one): scores kept when a grade moves
    or a deadline releases it, and posted. `services`: server/lti's ServiceClient; `platforms`: a platform by id."""

    def __init__(self, course: Course, store: LmsStore, services, platforms: Callable[[str], PlatformRow | None], now):
        self.course, self.store, self.services, self.platforms, self.now = course, store, services, platforms, now
        self._wake = threading.Event()
        self._changed: set[tuple[str, str]] = set()
        self._lock = threading.Lock()
        self._posting = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._swept = 0.0
        course.runs.listeners.append(self._graded)

    def wake(self) -> None:
        """A look now (the scores due on the clock as it is now, those changed)."""
        self._wake.set()

    def _graded(self, run_id: str, sid: str) -> None:
        """From a grading run's thread: a submission's row moved: its student's grade is looked at again by the
        poster (cheap here: the run's thread must not wait on an LMS)."""
        if len(sid) != 32:
            return
        whose = self.course.store.submission_of(sid)
        if whose is None:
            return
        with self._lock:
            self._changed.add(whose)
        self._wake.set()

    def release(self, aid: str, student: str) -> bool:
        """Keep the student's grade to send, if it is linked, theirs is graded and the policy shows the score
        to them now. True if a new score was kept."""
        a = self.course.store.assignment(aid)
        member = self.course.store.member(a["course_id"], student) if a else None
        if a is None or member is None or not member["lti_user"]:
            return False
        st = self.course.store.student(aid, student)
        if st is None:
            return False
        feedback = Feedback.model_validate(a["policy"]["feedback"])
        when = feedback.score_when()
        if when == When.never or (when == When.after_deadline and self.now() < self.course.deadlines(a, st)[1]):
            return False
        c = self.course.counting(a, self.course.submissions(a, student))
        if c is None:
            return False
        given, most = self.course.total(a, c)  # the manual part once released (server/course/manual.py)
        platform_id, sub = member["lti_user"].split(":", 1)
        kept = False
        for link in self.store.links(aid):
            if link["platform_id"] != platform_id or not link["lineitem"]:
                continue
            row = {"platform_id": platform_id, "lineitem": link["lineitem"], "user_id": sub, "assignment_id": aid,
                   "student": student, "score_given": round(given, 6),
                   "score_max": most}  # fmt: skip
            kept |= self.store.add_score(row, self.now())
        return kept

    def post_due(self) -> int:
        """Post the scores that are due (one round at a time); a failure leaves its row pending with a later
        try. The number posted."""
        with self._posting:
            return self._post_due()

    def _post_due(self) -> int:
        posted = 0
        for row in self.store.due(self.now(), POST_BATCH):
            platform = self.platforms(row["platform_id"])
            if platform is None:
                self.store.failed(row["id"], "the platform is no longer registered", self.now() + RETRY_MAX)
                continue
            stamp = datetime.fromtimestamp(row["timestamp"], UTC).isoformat(timespec="milliseconds")
            body = score_json(row["user_id"], row["score_given"], row["score_max"], stamp.replace("+00:00", "Z"),
                              row.get("comment"))  # fmt: skip
            try:
                self.services.post_score(platform, row["lineitem"], body)
            except Exception as e:  # noqa: BLE001 (a platform down: kept, tried again later; a refusal: kept, failed)
                if (status := for_good(e)) is not None:
                    self._refused(row, status, e)
                    continue
                wait = min(RETRY_MAX, RETRY_FIRST * 2 ** min(row["tries"], 12))
                self.store.failed(row["id"], str(e) or type(e).__name__, self.now() + wait)
                log.warning(
                    "grade for %s on %s not sent (%s); again in %.0f s", row["user_id"], row["lineitem"], e, wait
                )
                continue
            self.store.sent(row["id"], self.now())
            posted += 1
        return posted

    def _refused(self, row: LtiScoreRow, status: int, e: Exception) -> None:
        """The LMS refused the score for good: failed, with its status and message (the one place a score is
        marked so: an audit call goes here)."""
        message = getattr(e, "message", None) or str(e) or type(e).__name__
        self.store.refused(row["id"], status, message, self.now())
        log.warning("grade for %s on %s refused by the LMS for good (HTTP %d: %s); not tried again until sent again",
                    row["user_id"], row["lineitem"], status, message)  # fmt: skip

    def send_again(self, aid: str, sid: int | None = None) -> int:
        """Staff's "send again": the assignment's failed scores (or one) pending again, posted at the next round
        (now). How many (the one place failed scores are queued again: an audit call goes here)."""
        n = self.store.send_again(aid, self.now(), sid)
        if n:
            log.info("%d refused grade(s) of assignment %s queued to be sent again", n, aid)
            self.wake()
        return n

    def sweep(self) -> int:
        """Scores a deadline released (feedback after the deadline), and those changed since the last look."""
        with self._lock:
            changed, self._changed = self._changed, set()
        kept = sum(self.release(aid, student) for aid, student in changed)
        if self.now() - self._swept >= SWEEP_SECONDS:
            self._swept = self.now()
            for aid in self.store.linked_assignments():
                a = self.course.store.assignment(aid)
                if a is None:
                    continue
                for m in self.course.store.students(aid):
                    if m["lti_user"]:
                        kept += self.release(aid, m["student"])
        return kept

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="lti-grades", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.sweep()
                self.post_due()
            except Exception:  # noqa: BLE001 (the poster carries on: its rows say what is left)
                log.exception("grades back: a round failed")
            self._wake.wait(5.0)
            self._wake.clear()
