"""A grading render's terms and its outcome: the limits and seconds of each render the grader asks for
(the assignment's, within the service's), and what a finished render job's row means for the student."""

from __future__ import annotations

from server.core.settings import Settings
from server.jobs.lifecycle import JobStatus
from tracer.grading import RenderJob
from tracer.grading.renders import over_time
from tracer.scene import Limits


def capped(job: RenderJob, settings: Settings | None) -> tuple[Limits, float, str]:
    """The job's limits and seconds, each the smaller of the assignment's and the service's, and what
    set the seconds (for the message of a render stopped at its limit)."""
    if settings is None:
        return job.limits, job.max_seconds, job.limit_source
    limits = job.limits.tighter(settings.limits)
    if settings.max_job_seconds < job.max_seconds:
        return limits, settings.max_job_seconds, "the server's max_job_seconds, TRACER_MAX_JOB_SECONDS"
    return limits, job.max_seconds, job.limit_source


def job_outcome(row: dict, seconds: float, source: str) -> tuple[str | None, int, float]:
    """A finished job's row -> (why it has no image, or None; its spp; its render seconds). A job
    stopped at its time limit says what set the limit (`source`): the worker knows its row's seconds,
    not where they came from, so its message is replaced."""
    if row["status"] != JobStatus.done:
        error = row["error"] or f"the render job {row['id']} was {row['status']}"
        if row["status"] == JobStatus.failed and "over the time limit" in error:
            killed = "; its worker was killed" if "killed" in error else ""
            error = over_time(seconds, source) + killed
        return error, 0, 0.0
    took = (row["finished_at"] or 0) - (row["started_at"] or 0)
    return None, int(row["spp_done"]), max(0.0, took)
