"""The life of a render job: its statuses, which of them are final, and the moves between them.

    queued ──claim──> running ──finish──> done | failed | cancelled
       │                 │
       │                 └──requeue (worker stopping, worker died, server restarted)──> queued
       ├──cancel (before it started)──> cancelled
       └──lost again and again (its tries' worker hosts died before they could start it)──> failed

This is the one definition: the job store builds its SQL from it (a move is an UPDATE whose WHERE
names the status it leaves, checked against TRANSITIONS), the API reports `finished` from it, and
grading waits for it. A finished job never moves again; the janitor may remove it.

A job runs as tries (one per time a worker takes it). The rules of a try are named here too: why a
try stops before its job is done (`Stop`), how a try ended (`TryEnd`, each try's `outcome` in the
job's row), and what happens to a job whose try was lost with its worker (`after_lost`), which both
queue backends follow.
"""

from __future__ import annotations

from enum import StrEnum


class JobStatus(StrEnum):
    queued = "queued"  # waiting for a worker, by priority then age
    running = "running"  # a worker is rendering it
    done = "done"  # all samples rendered; the final image is kept
    failed = "failed"  # invalid at render time, over its time limit, or its worker died too often
    cancelled = "cancelled"  # DELETE /api/jobs/{id}; a running job keeps its last image

    @property
    def finished(self) -> bool:
        """True for the final statuses (done, failed, cancelled): no more progress, images or moves."""
        return self in FINISHED


FINISHED = frozenset({JobStatus.done, JobStatus.failed, JobStatus.cancelled})

TRANSITIONS: dict[JobStatus, frozenset[JobStatus]] = {  # status -> the statuses it may move to
    JobStatus.queued: frozenset({JobStatus.running, JobStatus.cancelled, JobStatus.failed}),
    JobStatus.running: frozenset({JobStatus.queued, JobStatus.done, JobStatus.failed, JobStatus.cancelled}),
    JobStatus.done: frozenset(),
    JobStatus.failed: frozenset(),
    JobStatus.cancelled: frozenset(),
}


class BadTransition(ValueError):
    """A move the life cycle does not allow (a bug in the caller, never a user's error)."""


def check_transition(source: JobStatus, target: JobStatus) -> None:
    """Raise BadTransition unless a job may move from `source` to `target`."""
    if target not in TRANSITIONS[source]:
        raise BadTransition(f"a job cannot move from {source} to {target}")


class JobKind(StrEnum):
    render = "render"  # an image, pass by pass (POST /api/jobs, grading's renders)
    raytree = "raytree"  # one pixel sample's ray tree (POST /api/raytree): a short job of its own
    preview = "preview"  # an example scene's preview, rendered ahead in the batch lane (server/jobs/previews.py)


class Lane(StrEnum):
    """Which work goes first: a worker takes interactive jobs before batch ones, and a batch render
    gives way at its next pass boundary when interactive work waits (it resumes where it stopped)."""

    interactive = "interactive"  # the page's renders and lessons, ray trees: short, someone is watching
    batch = "batch"  # long renders (estimated past TRACER_INTERACTIVE_SECONDS) and grading


LANES = (Lane.interactive, Lane.batch)  # in the order workers take them


LANE_RANK = {lane: rank for rank, lane in enumerate(LANES)}  # a lane's place in the order workers take them

RAYTREE_PRIORITY = 100  # a ray tree of a token is a click that waits for its answer: ahead of renders
ANONYMOUS_PRIORITY = 0  # one without a token: an anonymous job's default (JobCreate.priority)


class Stop(StrEnum):
    """Why a try stops before its job is done (a channel's `stop_reason`, server/queue/channel.py)."""

    cancel = "cancel"  # the job was cancelled (DELETE /api/jobs/{id}, a client that gave up)
    lost = "lost"  # the job is no longer this try's (its worker was taken for dead; another try has it)
    shutdown = "shutdown"  # the worker's host is stopping: the job goes back to the queue
    timeout = "timeout"  # past the job's time limit (TRACER_MAX_JOB_SECONDS, or a ray tree's)
    give_way = "yield"  # a batch render gives way to interactive work at a pass boundary


class TryEnd(StrEnum):
    """How a try ended: each try's `outcome` in the job's row, and what a try's `run` returns."""

    done = "done"  # the job is done
    failed = "failed"  # the job failed (an invalid scene, a render error, its time limit)
    cancelled = "cancelled"  # the job was cancelled while it ran
    lost = "lost"  # its worker died, or its host was cut off: the job runs again or fails (`after_lost`)
    given_back = "given back"  # its host stopped: the job went back to the queue, counting nothing lost
    gave_way = "gave way"  # to interactive work: the job went back to the queue, to continue from its film


def after_lost(lost_before: int, max_tries: int, cancel_requested: bool) -> JobStatus:
    """Where a job goes when a try of it is lost with its worker, `lost_before` tries having been lost
    already: cancelled if its cancel was accepted, queued again while fewer than `max_tries` tries are
    lost (TRACER_JOB_ATTEMPTS), else failed. A try given back or that gave way never counts."""
    if cancel_requested:
        return JobStatus.cancelled
    return JobStatus.queued if lost_before + 1 < max_tries else JobStatus.failed


def lost_error(reason: str, tries: int) -> str:
    """A job's error when it failed because its tries were lost."""
    return f"{reason}; tried {tries} time(s)"
