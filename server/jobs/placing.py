"""Where a render goes in the queue, by who asks: its lane and its priority (the policy of POST /api/jobs).

A render goes to the lane its estimate says (TRACER_INTERACTIVE_SECONDS: the interactive lane for short work, the
batch lane for the rest). Anyone may move their job down to the batch lane; only staff (the instructor) may move
one up, or give it a priority above 0: a student's long render asked for in the interactive lane would hold the
worker kept for everyone's short work, and a student's job is never put ahead of others'. What was asked and not
given is lowered (to the estimate's lane, to 0) and said in a warning at `lane` or `priority`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from server.jobs.lifecycle import Lane

STAFF_PRIORITY = (
    "a priority above 0 is the instructor's: {} was lowered to 0 (the job runs by its lane, then first come, "
    "first served)"
)
STAFF_LANE = (
    "the interactive lane is for work estimated at most TRACER_INTERACTIVE_SECONDS ({1:g} s); this render is "
    "estimated at {0:.0f} s, so it goes to the batch lane (only the instructor may move a job up)"
)


@dataclass(frozen=True)
class Placed:
    lane: Lane
    priority: int
    warnings: list[dict] = field(default_factory=list)  # what was asked and lowered, at `lane` or `priority`


def lane_for(seconds: float, interactive_seconds: float, asked: Lane | None = None, staff: bool = False) -> Lane:
    """The lane a render goes to: by its estimate; a caller may move it down, only staff may move it up."""
    estimated = Lane.interactive if seconds <= interactive_seconds else Lane.batch
    if asked is Lane.batch or (asked is Lane.interactive and staff):
        return asked
    return estimated


def place(seconds: float, interactive_seconds: float, lane: Lane | None, priority: int, staff: bool) -> Placed:
    """A render estimated at `seconds`, asked for in `lane` (None: by its estimate) with `priority`."""
    given = lane_for(seconds, interactive_seconds, lane, staff)
    warnings = []
    if priority > 0 and not staff:  # staff's: a student's job is never put ahead of others'
        warnings.append({"path": "priority", "message": STAFF_PRIORITY.format(priority)})
        priority = 0
    if lane is not None and given is not lane:
        warnings.append({"path": "lane", "message": STAFF_LANE.format(seconds, interactive_seconds)})
    return Placed(given, priority, warnings)
