"""Class statistics (server/course/stats.py, server/api/routes/stats.py): GET /api/assignments/{id}/stats and
stats.csv on a real server on loopback. A small assignment (the example's reference scene at 32 x 24: two
requirements and two image tests, 6 points) and a class of four whose work is known: ann gets full marks at
once; bea submits three times (2, 3, then 6 points five hours after her first); cid's first is invalid (no
attempt) and his second fails the glass requirement (2 points); dan submits nothing. Each statistic is checked
against those numbers; the CSV's rows, quoting and a name that would be a formula; a student's token gets the
404 of an unknown id, as on the dashboard. Time is the app's clock, moved between submissions, never slept to."""

from __future__ import annotations

import copy
import csv
import io
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import bearer, course_client, wait_for
from tests.support.scene import ROOT
from tests.support.stats import red, reference, small_spec

EXAMPLE = ROOT / "scenes" / "grading"
T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=2)


def invalid() -> dict:
    scene = copy.deepcopy(reference())
    scene["objects"][1]["radius"] = -1
    return scene


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("stats-data"), T0) as c:
        yield c


def test_stats_of_a_class_with_known_scores_attempts_and_times(app):
    clock = app.app.state.clock
    r = app.post("/api/assignments", json={"spec": small_spec(), "deadline": DEADLINE.isoformat()})
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    roster = 'id,name,email\nann,Ann A,\nbea,"=HYPERLINK(""http://x/"")",\ncid,"Cid, C",\ndan,Dan D,\n'
    r = app.post(f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv"})
    assert r.status_code == 200, r.text
    tok = {s["id"]: s["token"] for s in r.json()["students"]}

    empty = app.get(f"/api/assignments/{aid}/stats").json()
    assert empty["graded"] == 0
    assert empty["histogram"]["mean"] is None
    assert empty["fails_most"] == []
    assert [t["rate"] for t in empty["tests"]] == [None] * 5

    sids = []

    def hand(student: str, scene: dict, at: timedelta) -> None:
        clock.now = T0 + at
        r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(tok[student]))
        assert r.status_code == 202, r.text
        sids.append(r.json()["id"])

    hand("bea", red(glass=False), timedelta(0))
    hand("cid", invalid(), timedelta(0))
    hand("ann", reference(), timedelta(hours=1))
    hand("cid", red(glass=False), timedelta(hours=1))
    hand("bea", red(glass=True), timedelta(hours=2))
    hand("bea", reference(), timedelta(hours=5))
    for sid in sids:
        url = f"/api/assignments/{aid}/submissions/{sid}"
        wait_for(lambda u=url: app.get(u).json()["status"] in ("graded", "invalid", "failed"), 240, sid, 0.1)
    scores = [app.get(f"/api/assignments/{aid}/submissions/{sid}").json()["score"] for sid in sids]
    assert scores == [2.0, 0.0, 6.0, 2.0, 3.0, 6.0], scores  # the known work (the invalid one: 0)

    clock.now = T0 + timedelta(hours=6)
    st = app.get(f"/api/assignments/{aid}/stats")
    assert st.status_code == 200, st.text
    st = st.json()
    assert (st["students"], st["graded"], st["max_points"], st["tests_over"]) == (4, 3, 6.0, 3)
    # counting (the last graded): ann 6, bea 6, cid 2; tenths of 6 points: 2 in the 4th bar, 6 in the last
    bins = st["histogram"]["bins"]
    assert [b["count"] for b in bins] == [0, 0, 0, 1, 0, 0, 0, 0, 0, 2]
    assert (bins[3]["from"], bins[3]["to"], bins[9]["to"]) == (1.8, 2.4, 6.0)
    assert (st["histogram"]["mean"], st["histogram"]["median"]) == (round(14 / 3, 6), 6.0)
    rates = {t["test"]: (t["kind"], t["passed"], t["graded"], t["rate"]) for t in st["tests"]}
    assert rates == {
        "validity": ("validity", 3, 3, 1.0),
        "a glass object": ("requirement", 2, 3, round(2 / 3, 6)),
        "an area light": ("requirement", 3, 3, 1.0),
        "psnr": ("image", 2, 3, round(2 / 3, 6)),
        "pixels": ("image", 2, 3, round(2 / 3, 6)),
    }
    assert [t["test"] for t in st["tests"]] == ["validity", "a glass object", "an area light", "psnr", "pixels"]
    assert [(t["test"], t["failed"]) for t in st["fails_most"]] == [("a glass object", 1)]
    # attempts: ann 1, bea 3, cid 1 (his invalid one costs none), dan 0
    assert st["attempts"] == {
        "mean": 1.25, "median": 1.0, "max": 3,
        "students": [{"attempts": 0, "students": 1}, {"attempts": 1, "students": 2}, {"attempts": 2, "students": 0},
                     {"attempts": 3, "students": 1}],
    }  # fmt: skip
    # full marks: ann at once (0 s), bea 5 hours after her first; cid and dan never
    assert st["full_marks"] == {"students": 2, "submitted": 3, "median_seconds": 9000.0}
    per = {r["id"]: (r["submissions"], r["attempts"], r["points"], r["to_full_marks"]) for r in st["per_student"]}
    assert per == {
        "ann": (1, 1, 6.0, 0.0),
        "bea": (3, 3, 6.0, 18000.0),
        "cid": (2, 1, 2.0, None),
        "dan": (0, 0, None, None),
    }
    bea = next(r for r in st["per_student"] if r["id"] == "bea")
    assert (bea["first_at"], bea["full_marks_at"]) == ("2026-12-01T12:00:00Z", "2026-12-01T17:00:00Z")

    r = app.get(f"/api/assignments/{aid}/stats.csv")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv"), r.text
    assert 'filename="stats.csv"' in r.headers["content-disposition"]
    rows = list(csv.reader(io.StringIO(r.text)))
    assert rows[0] == ["id", "name", "state", "points", "max_points", "submissions", "attempts", "first_submitted",
                       "full_marks_at", "hours_to_full_marks", "test: validity", "test: a glass object",
                       "test: an area light", "test: psnr", "test: pixels"]  # fmt: skip
    got = {row[0]: row for row in rows[1:]}
    assert got["ann"][2:7] == ["graded", "6", "6", "1", "1"]
    assert got["ann"][9:] == ["0", *["passed"] * 5]
    assert got["bea"][1] == '\'=HYPERLINK("http://x/")'  # a formula kept as text, as every export
    assert got["bea"][5:7] == ["3", "3"]
    assert got["bea"][9] == "5"
    assert got["cid"][1] == "Cid, C"
    assert '"Cid, C"' in r.text  # quoted: one cell
    assert got["cid"][3] == "2"
    assert got["cid"][9:] == ["", "passed", "failed", "passed", "failed", "failed"]
    assert got["dan"][2:] == ["none", "", "6", "0", "0", "", "", "", "", "", "", "", ""]


def test_stats_are_the_staffs(app):
    """A TA of the course reads them; a student of the assignment gets the answer of an unknown id (as on the
    dashboard), a TA of another course what the dashboard answers them (401), a token of no one 401 or 403."""
    for cid in ("cs1", "cs2"):
        assert app.post("/api/courses", json={"id": cid, "name": cid}).status_code == 201
    r = app.post("/api/assignments?course=cs1", json={"spec": small_spec(), "deadline": DEADLINE.isoformat()})
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    r = app.post(f"/api/assignments/{aid}/roster", content="id,name,email\neve,Eve E,\n",
                 headers={"Content-Type": "text/csv"})  # fmt: skip
    eve = bearer(r.json()["students"][0]["token"])
    ta = {}
    for cid in ("cs1", "cs2"):
        r = app.post(f"/api/courses/{cid}/staff", json={"id": f"ta-{cid}", "name": "T A", "role": "ta"})
        assert r.status_code == 201, r.text
        ta[cid] = bearer(r.json()["token"])
    unknown = "0" * 32
    for path in ("stats", "stats.csv"):
        assert app.get(f"/api/assignments/{aid}/{path}", headers=ta["cs1"]).status_code == 200, path
        mine = app.get(f"/api/assignments/{aid}/{path}", headers=eve)
        nothing = app.get(f"/api/assignments/{unknown}/{path}", headers=eve)
        assert mine.status_code == nothing.status_code == 404, (path, mine.text)
        assert mine.text.replace(aid, unknown) == nothing.text, path
        assert app.get(f"/api/assignments/{aid}/dashboard", headers=eve).status_code == 404
        other = app.get(f"/api/assignments/{aid}/{path}", headers=ta["cs2"]).status_code
        assert other == app.get(f"/api/assignments/{aid}/dashboard", headers=ta["cs2"]).status_code == 401, path
        r = app.get(f"/api/assignments/{aid}/{path}", headers=bearer("not-a-token-of-anyone-here-at-all"))
        assert r.status_code in (401, 403), r.text
