"""The grading tables' rows, typed (server/grading/store.py): each type names its table's columns and no other,
and what the store's reads (and GradeRuns.item) return has exactly those keys, so that the type checker knows the
keys a run, the runs and the course's views read."""

from __future__ import annotations

import json

from server.core.settings import Settings
from server.grading.runs import GradeRuns
from server.grading.store import GradingItemRow, GradingRenderRow, GradingRunRow, GradingStore, ItemWithReport, Stage
from server.jobs.service import JobService
from server.jobs.store import JobStore
from server.queue.embedded.queue import EmbeddedQueue

RUN = "r" * 32


def columns(gs: GradingStore, table: str) -> set[str]:
    return {r["name"] for r in gs.db.execute(f"PRAGMA table_info({table})")}


def test_grading_rows_are_typed_with_every_column_of_their_tables(tmp_path):
    gs = GradingStore(tmp_path)
    for table, row in (("grading_runs", GradingRunRow), ("grading_items", GradingItemRow),
                       ("grading_renders", GradingRenderRow)):  # fmt: skip
        assert set(row.__required_keys__) == columns(gs, table), table
    assert set(ItemWithReport.__required_keys__) == columns(gs, "grading_items")
    assert ItemWithReport.__optional_keys__ == {"report"}  # once graded
    gs.create_run(RUN, "{}", "hw", 13.0, [{"student": "ann", "kind": "scene", "filename": "a.json", "file": "a"}])
    gs.update_item(RUN, "ann", stage=Stage.prepared, prepared={"job": None, "key": None})
    gs.add_render(RUN, "mean")
    gs.update_render(RUN, "mean", measured={"png/8": {}})
    assert set(gs.run(RUN)) == set(GradingRunRow.__required_keys__)
    item = gs.item(RUN, "ann")
    assert set(item) == set(GradingItemRow.__required_keys__)
    assert item["prepared"] == {"job": None, "key": None}  # parsed from its JSON
    assert [set(it) for it in gs.items(RUN)] == [set(GradingItemRow.__required_keys__)]
    renders = gs.renders(RUN)
    assert [set(r) for r in renders] == [set(GradingRenderRow.__required_keys__)]
    assert renders[0]["measured"] == {"png/8": {}}


def test_grading_a_graded_item_of_the_runs_has_its_report_too(tmp_path):
    """GradeRuns.item: a student's row, and `report` (their report.json) once graded: ItemWithReport's keys."""
    settings, store = Settings(data_dir=tmp_path, workers=0), JobStore(tmp_path)  # a queue that is never started
    runs = GradeRuns(settings, JobService(settings, store, EmbeddedQueue(settings, store), lambda: False))
    try:
        runs.gs.create_run(RUN, "{}", "hw", 13.0, [{"student": s, "kind": "scene", "filename": "", "file": ""}
                                                   for s in ("ann", "bob")])  # fmt: skip
        runs.gs.update_item(RUN, "ann", stage=Stage.graded, status="graded", score=13.0, max_score=13.0, row={})
        report = runs.root / RUN / "out" / "ann" / "report.json"
        report.parent.mkdir(parents=True)
        report.write_text(json.dumps({"score": 13.0}))
        graded = runs.item(RUN, "ann")
        assert set(graded) == set(ItemWithReport.__required_keys__) | {"report"}
        assert graded["report"] == {"score": 13.0}
        assert set(runs.item(RUN, "bob")) == set(ItemWithReport.__required_keys__)  # not graded: no report
    finally:
        runs.pool.shutdown()
