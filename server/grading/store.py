"""Grading runs as rows: three tables in the job store's database (DATA/jobs.sqlite3), beside `jobs`.

A run's record survives the API: a restarted server finds its runs still `running` here and resumes
each from where its rows say it was (server/grading/runs.py). The render jobs a run needs are ordinary
jobs of the `jobs` table (server/jobs/store.py owns it); a run keeps their ids, never a copy of their rows,
and reads their status with one query per look (`job_states`).

- `grading_runs`: one per POST /api/grade: the assignment as posted, status, the summary when done.
- `grading_renders`: the class's shared renders, the reference mean and one noise baseline per
  (sampler, spp, light samples): each one's job, its outcome, and the baseline's metrics per way of
  storing an image (`measured`), so a resumed run neither renders nor measures them again.
- `grading_open`: the runs that stay open for more students (a course assignment's version takes each
  submission as it comes: `add_item`); such a run is never done while it is open.
- `grading_items`: one per student: their submission's file, how far their grade got (`Stage`), what
  the first half of it found (`prepared`), their render job and its outcome, and once graded their
  summary row and exact score (report.json and the pictures are files in the run's folder).

Every write is one short statement or transaction; each thread opens its own connection (WAL).
"""

from __future__ import annotations

import json
import sqlite3
import time
from enum import StrEnum
from pathlib import Path
from typing import Any, TypedDict, cast

from server.core.db import Tables
from server.jobs.lifecycle import JobStatus

SCHEMA = """
CREATE TABLE IF NOT EXISTS grading_runs (
    id TEXT PRIMARY KEY,                  -- 32 hex digits
    status TEXT NOT NULL,                 -- running, done, failed (a job's words: server/jobs/lifecycle.py)
    name TEXT,                            -- the assignment's name
    assignment TEXT NOT NULL,             -- the assignment's JSON as posted (its reference scene inline)
    max_score REAL,                       -- the points of a scene submission
    created_at REAL NOT NULL,             -- Unix time (s)
    finished_at REAL,
    error TEXT,                           -- why it failed
    renders_total INTEGER,                -- renders the run needs (known once every submission is prepared)
    summary TEXT,                         -- the class summary (JSON), once done
    starts INTEGER NOT NULL DEFAULT 1     -- times a server took it up: 1, then one more per resume
);
CREATE TABLE IF NOT EXISTS grading_renders (
    run_id TEXT NOT NULL,
    key TEXT NOT NULL,                    -- "mean", or a baseline's [sampler, spp, light_samples] as JSON
    job_id TEXT,                          -- its render job (jobs.id), once queued
    status TEXT NOT NULL DEFAULT 'waiting', -- waiting, done, failed (RenderStatus)
    spp INTEGER,                          -- samples per pixel of the finished render
    seconds REAL,                         -- its render time
    error TEXT,                           -- why it has no image
    measured TEXT NOT NULL DEFAULT '{}',  -- a baseline's metrics by encoding ("png/8": {...})
    PRIMARY KEY (run_id, key)
);
CREATE TABLE IF NOT EXISTS grading_items (
    run_id TEXT NOT NULL,
    student TEXT NOT NULL,                -- the student's id (tracer.grading.student_name)
    position INTEGER NOT NULL,            -- order in the class (by student)
    kind TEXT NOT NULL,                   -- scene, png or exr
    filename TEXT NOT NULL,               -- the submitted file's name (in the zip, or as uploaded)
    file TEXT NOT NULL,                   -- where the run keeps it, relative to the run's folder
    stage TEXT NOT NULL,                  -- submitted, prepared, rendered, graded (Stage)
    prepared TEXT,                        -- tracer.grading.Prepared as JSON (validity, requirements, its render)
    job_id TEXT,                          -- its render job (jobs.id), once queued
    render TEXT,                          -- its render's outcome (JSON: image, spp, seconds, or error)
    status TEXT,                          -- graded, invalid, failed: the report's
    score REAL,                           -- exact, for the class statistics
    max_score REAL,
    row TEXT,                             -- its row of the summary (JSON)
    prepare_seconds REAL,                 -- time of each half of the grade in a worker process
    metrics_seconds REAL,
    PRIMARY KEY (run_id, student)
);
CREATE TABLE IF NOT EXISTS grading_open (
    run_id TEXT PRIMARY KEY               -- a run that takes submissions as they come (an assignment's version,
);                                        -- server/course/): it stays running while it is here
CREATE INDEX IF NOT EXISTS grading_runs_status ON grading_runs (status);
"""


class Stage(StrEnum):
    """How far a student's grade got. Each stage is kept, so a resumed run starts each student there."""

    submitted = "submitted"  # their file is in the run's folder
    prepared = "prepared"  # validity and requirements checked; the render it needs is known (and queued)
    rendered = "rendered"  # its render finished (done or not), or it needs none
    graded = "graded"  # report.json and the pictures written, score kept


class RenderStatus(StrEnum):
    waiting = "waiting"  # its job is queued or rendering
    done = "done"  # its image is in the run's folder
    failed = "failed"  # no image: `error` says why


class GradingRunRow(TypedDict):
    """A row of `grading_runs`, as GradingStore.run returns it (the assignment and summary as their JSON text)."""

    id: str
    status: str  # a JobStatus: running, done or failed
    name: str | None
    assignment: str  # JSON: the assignment as posted, its reference scene inline
    max_score: float | None
    created_at: float
    finished_at: float | None
    error: str | None
    renders_total: int | None
    summary: str | None  # JSON: the class summary, once done
    starts: int


class GradingItemRow(TypedDict):
    """A row of `grading_items`: one student's grade (their score), as GradingStore.item and .items return it,
    `prepared`, `render` and `row` parsed from their JSON (`Any`: a dict once their stage has them, None before;
    the run reads them where the stage says they are there)."""

    run_id: str
    student: str
    position: int
    kind: str  # scene, png or exr
    filename: str
    file: str  # relative to the run's folder
    stage: str  # a Stage
    prepared: Any  # tracer.grading.Prepared as JSON; None until prepared
    job_id: str | None
    render: Any  # its render's outcome (image, spp, seconds, or error); None until rendered
    status: str | None  # graded, invalid, failed: the report's
    score: float | None
    max_score: float | None
    row: Any  # its row of the summary; None until graded
    prepare_seconds: float | None
    metrics_seconds: float | None


class GradingRenderRow(TypedDict):
    """A row of `grading_renders`: one of the class's renders, as GradingStore.renders returns it, `measured`
    parsed from its JSON."""

    run_id: str
    key: str  # MEAN, or a baseline's [sampler, spp, light_samples] as JSON
    job_id: str | None
    status: str  # a RenderStatus
    spp: int | None
    seconds: float | None
    error: str | None
    measured: dict  # a baseline's metrics by encoding ("png/8": {...})


class ItemWithReport(GradingItemRow, total=False):
    """A student's row with their report (report.json, parsed; None where it is missing) once graded, as
    GradeRuns.item (server/grading/runs.py) returns it: what the course's views read of a submission's grade."""

    report: dict | None


class GradingStore(Tables):
    """The grading tables, in the database file of the job store `data_dir/jobs.sqlite3`."""

    def __init__(self, data_dir: Path):
        super().__init__(data_dir, SCHEMA)

    # -- runs ---------------------------------------------------------------------------------

    def create_run(
        self, run_id: str, assignment: str, name: str, max_score: float, items: list[dict], open_: bool = False
    ) -> None:
        """A run and its students (dicts: student, kind, filename, file), in one transaction; `open_`: it takes
        more students later (`add_item`) and stays running until `close`d."""
        with self._tx() as db:
            if open_:
                db.execute("INSERT INTO grading_open (run_id) VALUES (?)", (run_id,))
            db.execute(
                "INSERT INTO grading_runs (id, status, name, assignment, max_score, created_at)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (run_id, JobStatus.running, name, assignment, max_score, time.time()),
            )
            db.executemany(
                "INSERT INTO grading_items (run_id, student, position, kind, filename, file, stage)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                [(run_id, it["student"], i, it["kind"], it["filename"], it["file"], Stage.submitted)
                 for i, it in enumerate(items)],
            )  # fmt: skip

    def add_item(self, run_id: str, it: dict, db: sqlite3.Connection | None = None) -> bool:
        """One more student (a dict as create_run's) at the end of an open run; False if they are in it already
        (so handing a submission twice grades it once). On `db` when given: inside its caller's transaction (a
        course submission's row and this one are written together)."""
        cur = (db or self.db).execute(
            "INSERT OR IGNORE INTO grading_items (run_id, student, position, kind, filename, file, stage)"
            " SELECT ?1, ?2, COALESCE(MAX(position) + 1, 0), ?3, ?4, ?5, ?6 FROM grading_items WHERE run_id = ?1",
            (run_id, it["student"], it["kind"], it["filename"], it["file"], Stage.submitted),
        )
        return cur.rowcount == 1

    def is_open(self, run_id: str) -> bool:
        return self.db.execute("SELECT 1 FROM grading_open WHERE run_id = ?", (run_id,)).fetchone() is not None

    def close(self, run_id: str) -> None:
        """No more students: the run ends once those it has are graded."""
        self.db.execute("DELETE FROM grading_open WHERE run_id = ?", (run_id,))

    def item(self, run_id: str, student: str) -> GradingItemRow | None:
        row = self.db.execute("SELECT * FROM grading_items WHERE run_id = ? AND student = ?", (run_id, student))
        row = row.fetchone()
        return cast(GradingItemRow, _decoded(dict(row), ("prepared", "render", "row"))) if row else None

    def run(self, run_id: str) -> GradingRunRow | None:
        row = self.db.execute("SELECT * FROM grading_runs WHERE id = ?", (run_id,)).fetchone()
        return cast(GradingRunRow, dict(row)) if row else None

    def running(self) -> list[str]:
        """Runs that a server left unfinished, oldest first."""
        rows = self.db.execute("SELECT id FROM grading_runs WHERE status = ? ORDER BY created_at", (JobStatus.running,))
        return [r["id"] for r in rows]

    def update_run(self, run_id: str, **fields) -> None:
        sets = ", ".join(f"{k} = ?" for k in fields)
        self.db.execute(f"UPDATE grading_runs SET {sets} WHERE id = ?", (*fields.values(), run_id))

    def resumed(self, run_id: str) -> None:
        self.db.execute("UPDATE grading_runs SET starts = starts + 1 WHERE id = ?", (run_id,))

    def end_run(self, run_id: str, status: JobStatus, error: str | None = None, summary: dict | None = None) -> None:
        self.db.execute(
            "UPDATE grading_runs SET status = ?, error = ?, summary = ?, finished_at = ? WHERE id = ? AND status = ?",
            (status, error, json.dumps(summary) if summary else None, time.time(), run_id, JobStatus.running),
        )

    def progress(self, run_id: str) -> dict:
        """Students by stage, and renders finished (the class's and the students')."""
        stages = {s.value: 0 for s in Stage}
        for r in self.db.execute("SELECT stage, COUNT(*) AS n FROM grading_items WHERE run_id = ? GROUP BY stage",
                                 (run_id,)):  # fmt: skip
            stages[r["stage"]] = r["n"]
        done = self.db.execute(
            "SELECT (SELECT COUNT(*) FROM grading_renders WHERE run_id = ?1 AND status != ?2)"
            " + (SELECT COUNT(*) FROM grading_items WHERE run_id = ?1 AND job_id IS NOT NULL AND render IS NOT NULL)",
            (run_id, RenderStatus.waiting),
        ).fetchone()[0]
        return {"stages": stages, "renders_done": done}

    # -- students -----------------------------------------------------------------------------

    def items(self, run_id: str, after: int = -1) -> list[GradingItemRow]:
        """The run's students (those past position `after` only: an open run's newcomers)."""
        rows = self.db.execute(
            "SELECT * FROM grading_items WHERE run_id = ? AND position > ? ORDER BY position", (run_id, after)
        )
        return [cast(GradingItemRow, _decoded(dict(r), ("prepared", "render", "row"))) for r in rows]

    def students(self, run_id: str) -> list[str]:
        rows = self.db.execute("SELECT student FROM grading_items WHERE run_id = ? ORDER BY position", (run_id,))
        return [r["student"] for r in rows]

    def update_item(self, run_id: str, student: str, **fields) -> None:
        for key in ("prepared", "render", "row"):
            if key in fields and fields[key] is not None:
                fields[key] = json.dumps(fields[key])
        sets = ", ".join(f"{k} = ?" for k in fields)
        self.db.execute(
            f"UPDATE grading_items SET {sets} WHERE run_id = ? AND student = ?", (*fields.values(), run_id, student)
        )

    # -- the class's renders ------------------------------------------------------------------

    def renders(self, run_id: str) -> list[GradingRenderRow]:
        rows = self.db.execute("SELECT * FROM grading_renders WHERE run_id = ? ORDER BY rowid", (run_id,))
        return [cast(GradingRenderRow, _decoded(dict(r), ("measured",))) for r in rows]

    def add_render(self, run_id: str, key: str) -> None:
        self.db.execute("INSERT OR IGNORE INTO grading_renders (run_id, key) VALUES (?, ?)", (run_id, key))

    def update_render(self, run_id: str, key: str, **fields) -> None:
        if "measured" in fields:
            fields["measured"] = json.dumps(fields["measured"])
        sets = ", ".join(f"{k} = ?" for k in fields)
        self.db.execute(
            f"UPDATE grading_renders SET {sets} WHERE run_id = ? AND key = ?", (*fields.values(), run_id, key)
        )


def _decoded(row: dict, keys: tuple[str, ...]) -> dict:
    for key in keys:
        if row.get(key) is not None:
            row[key] = json.loads(row[key])
    return row
