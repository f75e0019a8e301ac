"""Class statistics of one assignment (GET /api/assignments/{aid}/stats and stats.csv, docs/assignments.md,
"Class statistics"): what the instructor's dashboard (web/js/course/stats.js) draws beside the roster.

**Whose submission.** Each roster student's counting submission is the dashboard's and the grades' (
`dashboard.student_rows`, which is `Course.class_grades` and `Course.counting`: the last graded or the best, as
the policy says); its points are the dashboard's (the score after the late penalty, in the spec's points; with
staff-graded items, plus the manual part graded so far, out of the spec's points and the items').

- `histogram`: the counting points in tenths of the spec's points (the dashboard's Scores bars: a score of
  exactly the maximum is in the last bar), with the mean and the median.
- `tests`: each test of the spec (validity, the requirements, the image tests) with how many counting
  submissions it was graded in and how many passed it (every point of it); `rate` = passed / graded. A
  requirement is graded in scenes only (an image has none). A test of an earlier version (the assignment was
  edited and not regraded) is listed after the current spec's.
- `fails_most`: the requirement(s) that the most counting submissions fail (ties all listed, the spec's order);
  empty when none fails.
- `attempts`: per student the submissions made and the attempts among them (an invalid or ungradable
  submission costs no attempt, as the brief counts them), and the class's mean, median, maximum and the number
  of students at each count of attempts.
- `full_marks`: per student the time from their first submission (whatever it became) to their first
  submission graded with every test passed (the work's full marks, a late penalty aside), and the median over
  those who got there.

**Cost.** The class is what its staff put on the roster (uploads of at most max_body_bytes each, an LMS's
roster) plus at most max_joins_per_assignment self-declared joins: no student can grow it, and the staff's
dashboard reads the same rows every few seconds. This is the dashboard's work (one query of the submissions)
plus one report.json per student (their counting submission's), at most MAX_STUDENTS of those: past it the
tests are counted over the first MAX_STUDENTS students and `tests_over` says so. Nothing is kept: each GET
computes it, for the course's staff only.
"""

from __future__ import annotations

import io
import statistics

from server.course import dashboard
from server.course.assignments import test_keys
from server.course.base import iso, report_keys, status_of
from server.course.dashboard import student_rows
from server.course.schema import AssignmentRow, SubmissionWithGrade
from server.course.service import Course
from tracer.tools import spreadsheet

BINS = 10  # the histogram's bars: tenths of the spec's points (web/js/course/instructor_board.js's BINS)
MAX_STUDENTS = 5000  # counting submissions whose report.json is read for the tests' pass rates
NOT_ATTEMPTS = ("invalid", "failed")  # statuses that cost no attempt (submission_store.HOLDS_ATTEMPT)


def _round(x: float | None, digits: int = 6) -> float | None:
    return None if x is None else round(x, digits)


def _median(xs: list[float]) -> float | None:
    return _round(statistics.median(xs)) if xs else None


def _mean(xs: list[float]) -> float | None:
    return _round(statistics.fmean(xs)) if xs else None


def histogram(points: list[float], max_points: float) -> list[dict]:
    """Tenths of `max_points`: each bar's [from, to) and its count (the last bar holds the maximum too)."""
    top = max_points or 1
    counts = [0] * BINS
    for p in points:
        counts[min(BINS - 1, max(0, int(p / top * BINS)))] += 1
    return [
        {"from": _round(i * top / BINS), "to": _round((i + 1) * top / BINS), "count": n} for i, n in enumerate(counts)
    ]


def _tests_of(course: Course, a: AssignmentRow, sub: SubmissionWithGrade) -> dict[str, dict]:
    """The counting submission's tests by the policy's key: {name, kind, passed}."""
    item = course.runs.item(sub["run_id"], sub["id"]) or {}
    report = item.get("report") or {}
    keys = report_keys(course.spec(a["id"], sub["version"]), sub["kind"])
    out = {}
    for key, t in zip(keys, report.get("tests", []), strict=False):
        out[key] = {"name": t.get("name", key), "kind": t.get("kind"), "passed": t.get("status") == "passed"}
    return out


def _kind(spec, key: str) -> str:
    if key == "validity":
        return "validity"
    return "requirement" if key in {r.name for r in spec.requirements} else "image"


def student_stats(course: Course, a: AssignmentRow) -> tuple[list[dict], dict[str, dict[str, dict]]]:
    """Each roster student's statistics (in roster order) and their counting submission's tests by key."""
    rows = student_rows(course, a)  # the dashboard's rows: state, points and the counting submission's id
    subs: dict[str, list[SubmissionWithGrade]] = {}
    for s in course.submissions(a):  # in the order they came (a student who joined since: none yet)
        subs.setdefault(s["student"], []).append(s)
    out, tests = [], {}
    for row in rows:
        mine = subs.get(row["id"], [])
        counting = next((s for s in mine if s["id"] == row["counting"]), None)
        attempts = sum(status_of(s) not in NOT_ATTEMPTS for s in mine)
        first = mine[0]["accepted_at"] if mine else None
        full = next(
            (
                s
                for s in mine
                if status_of(s) == "graded" and s["score"] is not None and s["score"] >= (s["max_score"] or 0) > 0
            ),
            None,
        )
        out.append(
            {
                "id": row["id"],
                "name": row["name"],
                "state": row["state"],
                "points": row["points"],
                "submissions": len(mine),
                "attempts": attempts,
                "first_at": iso(first),
                "full_marks_at": iso(full["accepted_at"]) if full else None,
                "to_full_marks": _round(full["accepted_at"] - first, 3) if full and first is not None else None,
            }
        )
        if counting is not None and len(tests) < MAX_STUDENTS:
            tests[row["id"]] = _tests_of(course, a, counting)
    return out, tests


def stats(course: Course, a: AssignmentRow) -> dict:
    """The assignment's class statistics (see the module's docstring)."""
    spec = course.spec(a["id"], a["version"])
    max_points = dashboard.max_points(course, a)  # the spec's points and its manual items' (dashboard.max_points)
    students, tests = student_stats(course, a)
    points = [r["points"] for r in students if r["points"] is not None]

    keys = test_keys(spec)
    names: dict[str, str] = {}
    kinds: dict[str, str] = {}
    for mine in tests.values():
        for key, t in mine.items():
            if key not in names:
                names[key], kinds[key] = t["name"], t["kind"] or _kind(spec, key)
                if key not in keys:
                    keys.append(key)  # an earlier version's test
    rates = []
    for key in keys:
        graded = [mine[key]["passed"] for mine in tests.values() if key in mine]
        passed = sum(graded)
        rates.append(
            {
                "test": key,
                "name": names.get(key, key),
                "kind": kinds.get(key) or _kind(spec, key),
                "graded": len(graded),
                "passed": passed,
                "failed": len(graded) - passed,
                "rate": _round(passed / len(graded)) if graded else None,
            }
        )
    requirements = [t for t in rates if t["kind"] == "requirement" and t["failed"] > 0]
    worst = max((t["failed"] for t in requirements), default=0)
    attempts = [r["attempts"] for r in students]
    counts: dict[int, int] = {}
    for n in attempts:
        counts[n] = counts.get(n, 0) + 1
    reached = [r["to_full_marks"] for r in students if r["to_full_marks"] is not None]
    return {
        "id": a["id"],
        "version": a["version"],
        "name": a["spec"]["name"],
        "max_points": max_points,
        "now": iso(course.now()),
        "students": len(students),
        "graded": len(points),
        "histogram": {
            "bins": histogram(points, max_points),
            "mean": _mean(points),
            "median": _median(points),
        },
        "tests": rates,
        "tests_over": len(tests),
        "fails_most": [t for t in requirements if t["failed"] == worst],
        "attempts": {
            "mean": _mean(attempts),
            "median": _median(attempts),
            "max": max(attempts, default=0),
            "students": [{"attempts": n, "students": counts.get(n, 0)} for n in range(max(attempts, default=0) + 1)],
        },
        "full_marks": {
            "students": len(reached),
            "submitted": sum(r["submissions"] > 0 for r in students),
            "median_seconds": _median(reached),
        },
        "per_student": students,
    }


def _num(x: float | None) -> str:
    return "" if x is None else f"{round(x, 6):g}"


def stats_csv(course: Course, a: AssignmentRow) -> str:
    """One row per roster student: id, name (its control and bidirectional characters out), state, points,
    max_points, submissions, attempts, first_submitted, full_marks_at, hours_to_full_marks, then each test of
    the spec: passed or failed in their counting submission (empty: no counting submission, or not graded
    there: a requirement of an image). Through tracer/tools/spreadsheet.py's writer, as every export."""
    spec = course.spec(a["id"], a["version"])
    keys = test_keys(spec)
    students, tests = student_stats(course, a)
    buf = io.StringIO()
    w = spreadsheet.writer(buf, lineterminator="\n")
    head = ["id", "name", "state", "points", "max_points", "submissions", "attempts", "first_submitted"]
    w.writerow([*head, "full_marks_at", "hours_to_full_marks", *(f"test: {k}" for k in keys)])
    for r in students:
        mine = tests.get(r["id"], {})
        hours = None if r["to_full_marks"] is None else r["to_full_marks"] / 3600
        w.writerow(
            [
                r["id"],
                " ".join(spreadsheet.clean_name(r["name"])[0].split()),
                r["state"],
                _num(r["points"]),
                _num(spec.max_score()),
                r["submissions"],
                r["attempts"],
                r["first_at"] or "",
                r["full_marks_at"] or "",
                _num(hours),
                *(("passed" if mine[k]["passed"] else "failed") if k in mine else "" for k in keys),
            ]
        )
    return buf.getvalue()
