"""What every part of a grading run shares (server/grading/run.py says how a run goes): the `RunContext` its runs
hand it, and its state: what is in flight in the grading processes, and the rows it keeps in memory (read by
`GradingRun._load`). The parts are mixins over `RunBase`, one concept each: run_renders.py (the render jobs),
run_tasks.py (the tasks in the grading processes), and run.py's `GradingRun` (its loop, a full disk waited out)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from server.core.settings import Settings
from server.grading.pool import GradingPool
from server.grading.store import GradingItemRow, GradingRenderRow, GradingStore
from server.jobs.service import JobService
from tracer.grading import Grader, RenderJob

MEAN = "mean"  # the key of the reference mean's row (a baseline's is its [sampler, spp, light_samples])


class RunItem(GradingItemRow, total=False):
    """A student's row as a run keeps it in memory: with its baseline's key and its image's encoding once looked
    up (run_tasks.py's `_key`: cached, dropped when it is prepared again)."""

    _key: str | None
    _enc: str | None


@dataclass(frozen=True)
class RunContext:
    """What a run needs of the service around it, handed in by GradeRuns (server/grading/runs.py), which this
    module never imports: the runs start their runs, a run only reports back through these."""

    settings: Settings
    gs: GradingStore  # the runs' rows
    jobs: JobService  # the render jobs (and their store's files)
    pool: GradingPool  # the grading processes
    root: Path  # <data_dir>/grades: a run's folder is root/<id>
    stopping: threading.Event  # set when the server stops: the run stops where it is (its rows say where)
    wake: Callable[[str], threading.Event]  # an open run's event, set when a student is added (GradeRuns.add)
    item_changed: Callable[[str, str], None]  # (run, student): a student's row moved; the listeners are told
    waiting_space: Callable[[str, str | None], None]  # (run, why): it waits for space on the disk; None: no more


class RunBase:
    """A run's state, for its parts (run_renders.py, run_tasks.py, run.py)."""

    text: str  # the assignment, as handed in (the rows from here on: `GradingRun._load`)
    grader: Grader
    tests: dict  # the assignment's image tests
    items: dict[str, RunItem]  # the students' rows, by student
    # the class's renders' rows, by key (MEAN, or a baseline's; looked up by a _key: None)
    renders: dict[Any, GradingRenderRow]
    renders_total: int | None  # None: counted once every student is prepared
    open: bool  # an open run takes students as they come

    def __init__(self, context: RunContext, run_id: str):
        self.context, self.id = context, run_id
        self.gs, self.service, self.settings, self.pool = context.gs, context.jobs, context.settings, context.pool
        self.store = context.jobs.store  # the render jobs' files
        self.folder = context.root / run_id
        self.flight: dict[Future, tuple[tuple, bool]] = {}  # future -> (task, submitted alone)
        self.suspects: set[tuple] = set()  # tasks in flight when the pool broke
        self.breaks: dict[tuple, int] = {}  # times a task broke the pool while it ran alone
        self.render_jobs: dict[str, RenderJob] = {}  # the class's render jobs, by key
        self.waited = False  # it met a full disk, and has not gone through a round of its loop since
