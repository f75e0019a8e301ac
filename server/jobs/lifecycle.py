"""The life of a render job: its statuses, which of them are final, and the moves between them.

    queued ──claim──> running ──finish──> done | failed | cancelled
       │                 │
       │                 └──requeue (worker stopping, worker died, server restarted)──> queued
       ├──cancel (before it started)──> cancelled
       └──lost again and again (its tries' worker hosts died before they could start it)──> failed

This is the one definition: the job store builds its SQL from it (a move is an UPDATE whose WHERE
names the status it leaves, checked against TRANSITIONS), the API reports `finished` from it, and
grading waits for it. A finished job never moves again; the janitor may remove it.
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
