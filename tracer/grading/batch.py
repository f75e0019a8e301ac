"""A class at once: submissions from a folder or a zip, one report per student, a class summary.

Layout of a folder (or a zip, with or without one top folder):
    alice.json            a scene
    bob.png / bob.exr     an image of the reference scene, from the student's own ray tracer
    carol/scene.json      a folder per student: its one .json (a scene), else its one .png or .exr

Written for each student (out/<student>/): results.json (Gradescope), report.json, render.png,
reference.png, error_map.png (FLIP), rejected.png (pixels the z test rejected, red); for the
class: summary.csv and summary.json.
"""

from __future__ import annotations

import io
import json
from pathlib import Path, PurePosixPath

from tracer.grading.archive import MAX_FILE_BYTES, SUFFIXES, Caps, read_zip
from tracer.grading.metrics import GradingError
from tracer.grading.report import Report
from tracer.grading.submission import Submission, student_name
from tracer.tools import spreadsheet

MAX_FILES = 2000  # files of a class read from a folder (and kept from a zip) by the CLI


def student_for_file(name: str) -> str:
    """A submitted file's name -> its student: the name without its folders and last suffix, made safe
    by student_name ("hw4/Zoë O'Brien.json" -> "Zoë_O_Brien"). The CLI, a class folder or zip, and the
    page (through POST /api/grade/students) all name students by this one rule."""
    return student_name(PurePosixPath(name.replace("\\", "/")).stem)


def _pick(names: list[str]) -> tuple[str, str] | None:
    """A student's folder -> (their file, its kind): the one scene, else the one image."""
    by_kind: dict[str, list[str]] = {}
    for name in sorted(names):
        kind = SUFFIXES.get(PurePosixPath(name).suffix.lower())
        if kind:
            by_kind.setdefault("scene" if kind == "scene" else "image", []).append(name)
    for group in ("scene", "image"):
        if by_kind.get(group):
            name = by_kind[group][0]
            return name, SUFFIXES[PurePosixPath(name).suffix.lower()]
    return None


def group_names(names: list[str]) -> list[tuple[str, str, str]]:
    """Relative POSIX paths of a class's files -> (student, path, kind), one per student, sorted by
    student, by the layout above (the files themselves are not needed: they may be on disk or in memory)."""
    parts = {p: PurePosixPath(p).parts for p in names}
    short = {p: p for p in names}  # the name inside the one top folder, if there is one
    tops = {ps[0] for ps in parts.values() if len(ps) > 1}
    if len(tops) == 1 and all(len(ps) > 1 for ps in parts.values()):  # one top folder: look inside it
        short = {p: str(PurePosixPath(*parts[p][1:])) for p in names}
        parts = {p: PurePosixPath(short[p]).parts for p in names}
    subs: dict[str, tuple[str, str, str]] = {}
    folders: dict[str, dict[str, str]] = {}
    for path in sorted(names, key=lambda p: short[p]):
        ps = parts[path]
        if len(ps) == 1:
            kind = SUFFIXES.get(PurePosixPath(path).suffix.lower())
            if kind:
                student = student_for_file(path)
                subs.setdefault(student, (student, path, kind))
        else:
            folders.setdefault(ps[0], {})[short[path]] = path
    for folder, files in sorted(folders.items()):
        student = student_name(folder)
        if student not in subs and (picked := _pick(list(files))) is not None:
            subs[student] = (student, files[picked[0]], picked[1])
    return [subs[k] for k in sorted(subs)]


def group_files(entries: dict[str, bytes]) -> list[Submission]:
    """Relative POSIX paths -> submissions, by the layout above."""
    out = []
    for student, path, kind in group_names(list(entries)):
        out.append(Submission(student, entries[path], kind, _inside(path, entries)))
    return out


def _inside(path: str, entries: dict) -> str:
    """A file's name inside the class's one top folder, if all its files are in one (as it was shown)."""
    parts = {PurePosixPath(p).parts for p in entries}
    tops = {ps[0] for ps in parts if len(ps) > 1}
    if len(tops) == 1 and all(len(ps) > 1 for ps in parts):
        return str(PurePosixPath(*PurePosixPath(path).parts[1:]))
    return path


def collect(path: Path) -> list[Submission]:
    """A folder or a .zip of submissions -> one Submission per student, sorted by name."""
    entries: dict[str, bytes] = {}
    if path.is_dir():
        for f in sorted(path.rglob("*")):
            rel = f.relative_to(path).as_posix()
            if f.is_file() and not any(part.startswith(".") for part in PurePosixPath(rel).parts):
                if f.stat().st_size > MAX_FILE_BYTES:
                    raise GradingError(f"{rel}: larger than {MAX_FILE_BYTES} bytes")
                entries[rel] = f.read_bytes()
    else:
        try:
            with open(path, "rb") as f:
                entries = read_zip(f, Caps())
        except OSError as e:
            raise GradingError(f"cannot read {path}: {e.strerror}") from None
    if len(entries) > MAX_FILES:
        raise GradingError(f"{len(entries)} files; at most {MAX_FILES}")
    return group_files(entries)


# ----------------------------------------------------------------------------------------- output


def percent(score: float, max_score: float) -> float | None:
    """A score as a percentage of its maximum (None when there is nothing to earn), to 2 decimals."""
    return round(100.0 * score / max_score, 2) if max_score > 0 else None


def summary_row(r: Report) -> dict:
    """A student's row of the summary: score, maximum, percent, status, each test's score, the metrics."""
    row = {"student": r.student, "kind": r.kind, "status": r.status, "score": round(r.score, 6),
           "max_score": round(r.max_score, 6), "percent": percent(r.score, r.max_score)}  # fmt: skip
    for t in r.tests:
        row[t.name] = round(t.score, 6)
    for k in ("flip", "ssim", "psnr", "rejected"):
        row[k] = r.metrics.get(k)
    return row


def summary(reports: list[Report]) -> dict:
    """The class: a row per student (score, maximum, percent, status, each test's score, the metrics) and
    statistics in percent (a scene is out of more points than an image, so points do not average)."""
    assignment = reports[0].assignment if reports else None
    return class_summary(assignment, [summary_row(r) for r in reports], [(r.score, r.max_score) for r in reports])


def class_summary(assignment: str | None, rows: list[dict], scores: list[tuple[float, float]]) -> dict:
    """The summary from each student's row (`summary_row`) and exact (score, max_score): what `summary`
    gives, for a service that keeps the rows rather than the reports. `max_scores`: the maximum of each kind
    of submission in the class (a scene's, an image's: its image tests only)."""
    shares = [100.0 * score / top for score, top in scores if top > 0]
    max_scores: dict[str, float] = {}
    for row in rows:
        max_scores[row["kind"]] = max(max_scores.get(row["kind"], 0.0), row["max_score"])
    stats = {
        "students": len(rows),
        "max_scores": dict(sorted(max_scores.items(), key=lambda kv: kv[0] != "scene")),
        "mean_percent": round(sum(shares) / len(shares), 2) if shares else None,
        "min_percent": round(min(shares), 2) if shares else None,
        "max_percent": round(max(shares), 2) if shares else None,
        "by_status": {s: sum(row["status"] == s for row in rows) for s in ("graded", "invalid", "failed")},
    }
    return {"assignment": assignment, "statistics": stats, "students": rows}


def summary_csv(table: dict) -> str:
    rows = table["students"]
    columns: list[str] = []
    for row in rows:
        columns += [c for c in row if c not in columns]
    buf = io.StringIO()
    w = spreadsheet.writer(buf, lineterminator="\n")  # a student's name cannot start a formula
    w.writerow(columns)
    for row in rows:
        w.writerow(["" if row.get(k) is None else row.get(k) for k in columns])
    return buf.getvalue()


def write_report(folder: Path, report: Report) -> None:
    """One student's files: results.json (Gradescope), report.json and the pictures as PNG."""
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.json").write_text(json.dumps(report.gradescope(), indent=2) + "\n")
    (folder / "report.json").write_text(json.dumps(report.to_json(), indent=2) + "\n")
    for name, pixels in report.images.items():
        Image.fromarray(pixels, "RGB").save(folder / f"{name}.png")


def write_all(out: Path, reports: list[Report]) -> dict:
    """Every student's files under out/<student>/, and out/summary.csv + summary.json; returns the summary."""
    out.mkdir(parents=True, exist_ok=True)
    for r in reports:
        write_report(out / r.student, r)
    table = summary(reports)
    write_summary(out, table)
    return table


def write_summary(out: Path, table: dict) -> None:
    """The class's summary.json and summary.csv."""
    (out / "summary.json").write_text(json.dumps(table, indent=2) + "\n")
    (out / "summary.csv").write_text(summary_csv(table))
