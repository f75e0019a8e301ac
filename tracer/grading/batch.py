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

import csv
import io
import json
import zipfile
from pathlib import Path, PurePosixPath

from tracer.grading.grade import Report, Submission, student_name
from tracer.grading.metrics import GradingError

MAX_FILE_BYTES = 20_000_000  # one submitted file
MAX_FILES = 2000
SUFFIXES = {".json": "scene", ".png": "png", ".exr": "exr"}


def student_for_file(name: str) -> str:
    """A submitted file's name -> its student: the name without its folders and last suffix, made safe
    by student_name ("hw4/Zoë O'Brien.json" -> "Zoë_O_Brien"). The CLI, a class folder or zip, and the
    page (through POST /api/grade/students) all name students by this one rule."""
    return student_name(PurePosixPath(name.replace("\\", "/")).stem)


def _pick(files: dict[str, bytes], student: str) -> Submission | None:
    """A student's folder -> their submission: the one scene, else the one image."""
    by_kind: dict[str, list[str]] = {}
    for name in sorted(files):
        kind = SUFFIXES.get(PurePosixPath(name).suffix.lower())
        if kind:
            by_kind.setdefault("scene" if kind == "scene" else "image", []).append(name)
    for group in ("scene", "image"):
        names = by_kind.get(group, [])
        if names:
            name = names[0]
            return Submission(student, files[name], SUFFIXES[PurePosixPath(name).suffix.lower()], name)
    return None


def group_files(entries: dict[str, bytes]) -> list[Submission]:
    """Relative POSIX paths -> submissions, by the layout above."""
    parts = {p: PurePosixPath(p).parts for p in entries}
    tops = {ps[0] for ps in parts.values() if len(ps) > 1}
    if len(tops) == 1 and all(len(ps) > 1 for ps in parts.values()):  # one top folder: look inside it
        entries = {str(PurePosixPath(*parts[p][1:])): d for p, d in entries.items()}
        parts = {p: PurePosixPath(p).parts for p in entries}
    subs: dict[str, Submission] = {}
    folders: dict[str, dict[str, bytes]] = {}
    for path, data in sorted(entries.items()):
        ps = parts[path]
        if len(ps) == 1:
            kind = SUFFIXES.get(PurePosixPath(path).suffix.lower())
            if kind:
                student = student_for_file(path)
                subs.setdefault(student, Submission(student, data, kind, path))
        else:
            folders.setdefault(ps[0], {})[path] = data
    for folder, files in sorted(folders.items()):
        student = student_name(folder)
        if student not in subs and (sub := _pick(files, student)) is not None:
            subs[student] = sub
    return [subs[k] for k in sorted(subs)]


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
            data = path.read_bytes()
        except OSError as e:
            raise GradingError(f"cannot read {path}: {e.strerror}") from None
        entries = read_zip(data)
    if len(entries) > MAX_FILES:
        raise GradingError(f"{len(entries)} files; at most {MAX_FILES}")
    return group_files(entries)


def read_zip(data: bytes) -> dict[str, bytes]:
    """The files of a zip, by relative path; absolute paths, '..' and hidden files are skipped, and a
    file larger than MAX_FILE_BYTES (unpacked) is an error, so a zip bomb stops early."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile as e:
        raise GradingError(f"not a zip file: {e}") from None
    out = {}
    with zf:
        for info in zf.infolist():
            p = PurePosixPath(_zip_name(info))
            hidden = any(s.startswith((".", "__MACOSX")) for s in p.parts)
            if info.is_dir() or p.is_absolute() or ".." in p.parts or hidden:
                continue
            if info.file_size > MAX_FILE_BYTES:
                raise GradingError(f"{info.filename}: larger than {MAX_FILE_BYTES} bytes unpacked")
            out[str(p)] = zf.read(info)
        if len(out) > MAX_FILES:
            raise GradingError(f"{len(out)} files; at most {MAX_FILES}")
    return out


def _zip_name(info: zipfile.ZipInfo) -> str:
    """A member's name: zips without the UTF-8 flag are read as code page 437 (the zip standard), but
    many tools (macOS, Linux) write UTF-8 without setting it, so "Zoë.json" would come out "Zo├½.json"."""
    if info.flag_bits & 0x800:
        return info.filename
    try:
        return info.filename.encode("cp437").decode("utf-8")
    except UnicodeError:  # really code page 437 (or another one we cannot tell): as read
        return info.filename


# ----------------------------------------------------------------------------------------- output


def percent(score: float, max_score: float) -> float | None:
    """A score as a percentage of its maximum (None when there is nothing to earn), to 2 decimals."""
    return round(100.0 * score / max_score, 2) if max_score > 0 else None


def summary(reports: list[Report]) -> dict:
    """The class: a row per student (score, maximum, percent, status, each test's score, the metrics) and
    statistics in percent (a scene is out of more points than an image, so points do not average)."""
    rows = []
    for r in reports:
        row = {"student": r.student, "kind": r.kind, "status": r.status, "score": round(r.score, 6),
               "max_score": round(r.max_score, 6), "percent": percent(r.score, r.max_score)}  # fmt: skip
        for t in r.tests:
            row[t.name] = round(t.score, 6)
        for k in ("flip", "ssim", "psnr", "rejected"):
            row[k] = r.metrics.get(k)
        rows.append(row)
    shares = [100.0 * r.score / r.max_score for r in reports if r.max_score > 0]
    stats = {
        "students": len(reports),
        "mean_percent": round(sum(shares) / len(shares), 2) if shares else None,
        "min_percent": round(min(shares), 2) if shares else None,
        "max_percent": round(max(shares), 2) if shares else None,
        "by_status": {s: sum(r.status == s for r in reports) for s in ("graded", "invalid", "failed")},
    }
    return {"assignment": reports[0].assignment if reports else None, "statistics": stats, "students": rows}


def summary_csv(table: dict) -> str:
    rows = table["students"]
    columns: list[str] = []
    for row in rows:
        columns += [c for c in row if c not in columns]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in columns})
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
    (out / "summary.json").write_text(json.dumps(table, indent=2) + "\n")
    (out / "summary.csv").write_text(summary_csv(table))
    return table
