"""bench.similarity (issue #41, item 6) at a small size: a class of 60 that started from one starter scene, two
of whom handed in another's scene disguised (reordered, renamed, nudged), and the same with pictures; the report
flags exactly the copies, first, and none of the honest students, well inside its time."""

from __future__ import annotations

import json

from bench import similarity


def test_bench_similarity_scenes_flags_the_copies_and_no_one_else(tmp_path, capsys):
    result = similarity.main(["--students", "60", "--copies", "2", "--json", str(tmp_path / "out.json")])
    assert result["copies_flagged_first"] and result["flagged"] == 2 and result["honest_flagged"] == 0, result
    assert result["candidates"] < result["all_pairs"] / 10, result  # banding: not every pair compared exactly
    assert result["seconds"] < 30, result
    assert json.loads((tmp_path / "out.json").read_text())["students"] == 60
    assert "copies_flagged_first  True" in capsys.readouterr().out


def test_bench_similarity_images_flags_the_copies_and_no_one_else():
    result = similarity.main(["--students", "40", "--copies", "2", "--images"])
    assert result["copies_flagged_first"] and result["flagged"] == 2 and result["honest_flagged"] == 0, result
