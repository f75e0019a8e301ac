"""A grading run's tasks in the grading processes (server/grading/run.py says how a run goes): a student prepared
(tracer.grading.tasks.prepare_submission), a noise baseline measured once per way of storing images, a student's
image tests graded (tracer.grading.tasks.grade_metrics); each task's result kept in its row.

Each task goes to the grading processes with at most FLIGHT_PER_PROCESS per process in flight. A
process that dies breaks the pool: the tasks that were in flight become suspects and run again one at
a time, so the one that kills its process is found and fails alone (twice alone: failed).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from functools import partial
from typing import Any, cast

from server.core.files import is_disk_full
from server.grading.run_base import MEAN, RunItem
from server.grading.run_renders import RunRenders
from server.grading.store import GradingRenderRow, RenderStatus, Stage
from tracer.grading import Prepared, Report, Submission, tasks
from tracer.grading.batch import summary_row, write_report
from tracer.grading.imagetests import finish_report

log = logging.getLogger(__name__)

FLIGHT_PER_PROCESS = 2  # tasks of one run in the grading pool at once, per process


def _key(it: RunItem) -> str | None:
    """A prepared student's baseline: its row's key ([sampler, spp, light_samples] as JSON), kept in the item."""
    if "_key" not in it:
        p = it["prepared"]
        it["_key"] = json.dumps(list(p["key"])) if p is not None and p["key"] is not None else None
        it["_enc"] = f"{p['encoding'][0]}/{p['encoding'][1]}" if p is not None else None
    return it["_key"]


def _encoding(it: RunItem) -> str:
    """How a prepared student's image is stored ("png/8", "render/32"): a baseline is measured once per one."""
    _key(it)
    return cast(str, it.get("_enc"))  # (set by `_key`: a str once prepared, and only prepared students are asked)


class RunTasks(RunRenders):
    """The tasks of a run in the grading processes (a mixin of GradingRun, server/grading/run.py)."""

    def _schedule(self) -> None:
        for it in self.items.values():  # what a server stopped between two writes left undone
            if it["stage"] in (Stage.prepared, Stage.rendered) and (key := _key(it)) is not None:
                self._queue_render(key)
            if it["stage"] == Stage.prepared and not it["job_id"]:
                self._queue_item(it)
        if self.renders_total is None and all(it["stage"] != Stage.submitted for it in self.items.values()):
            students = sum(it["prepared"]["job"] is not None for it in self.items.values())
            self.renders_total = len(self.renders) + students
            self.gs.update_run(self.id, renders_total=self.renders_total)
        if self.suspects:  # after a process died: the tasks that were in flight, one at a time
            if not self.flight:
                for task, fn, kwargs in self._ready():
                    if task in self.suspects:
                        self.flight[self.pool.submit(fn, **kwargs())] = (task, True)
                        break
            return
        room = self.pool.processes * FLIGHT_PER_PROCESS - len(self.flight)
        for task, fn, kwargs in self._ready():
            if room <= 0:
                break
            self.flight[self.pool.submit(fn, **kwargs())] = (task, False)
            room -= 1

    def _ready(self) -> Iterator[tuple[tuple, Callable, Callable[[], dict]]]:
        """The tasks whose inputs are all there and that are not in flight, baselines first (many students
        wait for each): (task, function, its arguments when asked for)."""
        busy = {task for task, _ in self.flight.values()}
        mean = self.renders.get(MEAN)
        if mean is not None and mean["status"] == RenderStatus.done:
            wanted: dict[str, set[str]] = {}  # baseline -> the encodings of its students
            for it in self.items.values():
                if (key := _key(it)) is not None:
                    wanted.setdefault(key, set()).add(_encoding(it))
            for key, r in list(self.renders.items()):
                if key == MEAN or r["status"] == RenderStatus.waiting:
                    continue
                for enc in sorted(wanted.get(key, set()) - set(r["measured"])):
                    if r["status"] == RenderStatus.failed:  # nothing to measure: the students are told why
                        self._measured(key, enc, {"error": r["error"]})
                    elif ("baseline", key, enc) not in busy:
                        yield ("baseline", key, enc), tasks.measure_baseline, partial(self._baseline_args, r, enc)
        for s, it in self.items.items():
            if it["stage"] == Stage.submitted and ("prepare", s) not in busy:
                yield ("prepare", s), tasks.prepare_submission, partial(self._prepare_args, it)
        for s, it in self.items.items():
            if it["stage"] == Stage.rendered and ("metrics", s) not in busy and self._inputs_ready(it):
                yield ("metrics", s), tasks.grade_metrics, partial(self._metrics_args, it)

    def _prepare_args(self, it: RunItem) -> dict:
        return dict(assignment=self.text, student=it["student"], kind=it["kind"], path=str(self.folder / it["file"]),
                    filename=it["filename"])  # fmt: skip

    def _baseline_args(self, r: GradingRenderRow, enc: str) -> dict:
        fmt, bits = enc.split("/")
        baseline = {"image": str(self.folder / "renders" / f"{r['job_id']}.exr"), "spp": r["spp"]}
        return dict(assignment=self.text, reference=self._reference(), baseline=baseline, key=json.loads(r["key"]),
                    encoding=[fmt, int(bits)])  # fmt: skip

    def _inputs_ready(self, it: RunItem) -> bool:
        """Whether everything a student's image tests may need has ended (tracer.grading.finish_report's
        order: no tests or a problem found while preparing, then the reference, their render, the baseline)."""
        p = it["prepared"]
        if p["report"]["errors"] or not self.tests or p["report"]["metrics"].get("problem"):
            return True
        mean = self.renders.get(MEAN)
        if mean is None or mean["status"] == RenderStatus.waiting:
            return False
        if mean["status"] == RenderStatus.failed or (it["render"] or {}).get("error"):
            return True
        base = self.renders.get(_key(it))
        return base is not None and _encoding(it) in base["measured"]

    def _reference(self) -> dict:
        mean = self.renders.get(MEAN)
        if mean is None or mean["status"] == RenderStatus.waiting:
            return {}
        if mean["status"] == RenderStatus.failed:
            return {"error": mean["error"]}
        name = self.folder / "renders" / cast(str, mean["job_id"])  # (done: its job's image taken)
        return {"mean": f"{name}.exr", "variance": f"{name}.variance.exr", "spp": mean["spp"]}

    def _metrics_args(self, it: RunItem) -> dict:
        p, render = it["prepared"], it["render"]
        if render and render.get("image"):
            render = {**render, "image": str(self.folder / render["image"])}
        base = self.renders.get(_key(it)) if _key(it) is not None else None
        return dict(
            assignment=self.text, prepared=p, out=str(self.folder / "out" / it["student"]),
            submission=str(self.folder / it["file"]), render=render, reference=self._reference(),
            baseline=base["measured"].get(_encoding(it)) if base else None,
        )  # fmt: skip

    def _collect(self, future: Future) -> None:
        task, alone = self.flight.pop(future)
        try:
            result = future.result()
        except BrokenProcessPool:
            if not alone:
                self.suspects.add(task)
                return
            self.breaks[task] = self.breaks.get(task, 0) + 1
            if self.breaks[task] < 2:
                return  # once more, alone (another run's task may have broken the pool this time)
            log.error("grading run %s: %s killed its grading process twice; it fails alone", self.id, task)
            self.suspects.discard(task)
            return self._failed(task, "its grading process died (twice; the server's log may say why)")
        except Exception as e:  # a bug, or a file the grading process could not read: this student alone fails
            if is_disk_full(e):  # not the student's: the run waits for space, and does the task again
                raise
            log.exception("grading run %s: %s failed", self.id, task)
            self.suspects.discard(task)
            return self._failed(task, f"grading error: {type(e).__name__}: {e}")
        self.suspects.discard(task)
        if task[0] == "prepare":
            self._prepared(task[1], result["prepared"], result["seconds"])
        elif task[0] == "baseline":
            self._measured(task[1], task[2], result)
        else:
            self._graded(task[1], result)

    def _prepared(self, student: str, p: dict, seconds: float | None) -> None:
        it = self.items[student]
        stage = Stage.prepared if p["job"] is not None else Stage.rendered
        it.update(prepared=p, stage=stage)
        it.pop("_key", None)
        self.gs.update_item(self.id, student, prepared=p, stage=stage, prepare_seconds=seconds)
        self.context.item_changed(self.id, student)
        if (key := _key(it)) is not None:
            self._queue_render(key)
        if p["job"] is not None:
            self._queue_item(it)

    def _measured(self, key: str, enc: str, metrics: dict) -> None:
        r = self.renders[key]
        r["measured"] = {**r["measured"], enc: metrics}
        self.gs.update_render(self.id, key, measured=r["measured"])

    def _graded(self, student: str, result: dict) -> None:
        row = result["row"]
        fields: dict[str, Any] = dict(stage=Stage.graded, status=row["status"], score=result["score"],
                                      max_score=result["max_score"], row=row,
                                      metrics_seconds=result["seconds"])  # fmt: skip
        self.items[student].update(**fields)
        self.gs.update_item(self.id, student, **fields)
        self.context.item_changed(self.id, student)

    def _failed(self, task: tuple, message: str) -> None:
        """A task that could not be done: its student (or those of a baseline) is told why, and the run goes on."""
        if task[0] == "baseline":
            return self._measured(task[1], task[2], {"error": message})
        it = self.items[task[1]]
        if task[0] == "prepare":
            kind = "scene" if it["kind"] == "scene" else "image"
            blank = Prepared(Submission(it["student"], b"", it["kind"], it["filename"]),
                             Report(it["student"], self.grader.assignment.name, kind))  # fmt: skip
            return self._prepared(it["student"], self.grader.unreadable(blank, message).to_json(), None)
        p = Prepared.from_json(it["prepared"])  # the image tests: not compared, with the reason
        p.report.metrics["problem"] = message
        report = finish_report(self.grader.assignment, p, None, None, dict)
        write_report(self.folder / "out" / it["student"], report)
        self._graded(it["student"], {"row": summary_row(report), "score": report.score,
                                     "max_score": report.max_score, "seconds": None})  # fmt: skip
