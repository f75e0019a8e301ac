"""bench.migrate (issue #39, item 3) at a small size: it makes the release's database with 8 000 roster rows,
upgrades it and checks that nothing was lost; migration 2 takes seconds (its correlated subqueries took 53 s on
8 000 rows), and the dry run's estimate comes with it."""

from __future__ import annotations

import json

from bench import migrate
from server.core.migrations import MIGRATIONS


def test_bench_migrate_runs_small_and_migration_2_is_not_quadratic(tmp_path, capsys):
    result = migrate.main(["--students", "8000", "--jobs", "2000", "--json", str(tmp_path / "out.json")])
    assert result["rows"] == {"jobs": 2000, "course_members": 900, "course_tokens": 8000, "course_enrolments": 8000}
    [(name, seconds)] = [(k, v) for k, v in result["applied_s"].items() if k.startswith("2 ")]
    assert seconds < 20, result  # linear: well under a second on an idle machine
    steps = result["dry_run"]["steps"]  # the copy, then each migration
    assert result["dry_run"]["estimate_s"] >= 0 and len(steps) == 1 + len(MIGRATIONS), result["dry_run"]
    assert json.loads((tmp_path / "out.json").read_text())["students"] == 8000
    assert '"upgrade_s"' in capsys.readouterr().out
