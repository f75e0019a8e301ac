"""A class handed in to a grading run through the API (POST /api/grade, /api/grade/upload; docs/grading.md), and
a run's files read back: the rules behind server/api/routes/grade.py, which only translates HTTP. Every refusal is
a domain error (server/core/errors.py) at the request's path: 422 (`Invalid`) for a body or a part that is wrong,
404 (`NotFound`) for an unknown run or file."""

from __future__ import annotations

import base64
import binascii
import json
from pathlib import Path

from server.core.errors import Invalid, NotFound
from server.core.jsondepth import json_depth
from server.core.settings import Settings
from server.grading.runs import STUDENT_FILES, GradeRuns, Handed
from server.grading.uploads import Upload
from server.jobs.lifecycle import JobStatus
from tracer.grading import AssignmentError, Caps, GradingError, group_names, student_name, unpack_zip
from tracer.grading.archive import kept
from tracer.grading.batch import _inside

NO_SUBMISSIONS = "no submissions in it (.json, .png or .exr files)"


def b64(text: str, where: str) -> bytes:
    try:
        return base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise Invalid.at(where, "expected base64 data") from None


def class_caps(settings: Settings) -> Caps:
    """How much of a class the service reads (docs/grading.md): the settings' caps."""
    return Caps(
        entries=settings.max_class_entries, total_bytes=int(settings.max_class_bytes),
        entries_name="TRACER_MAX_CLASS_ENTRIES", bytes_name="TRACER_MAX_CLASS_BYTES",
    )  # fmt: skip


def submissions(scene, subs: list | None, zip_: str | None, settings: Settings, staging: Path | None) -> list[Handed]:
    """A JSON body's submissions: one `scene`, a class as `subs` (each with .student and .scene or .image and
    .format), or a class as a base64 `zip_`, unpacked into `staging` (a folder of the run's disk) with the same
    bounded reader as an upload's: never more than a chunk of it in memory, whatever its headers say."""
    if scene is not None:
        text = scene if isinstance(scene, str) else json.dumps(scene)
        return [Handed("submission", "scene", "submission.json", text.encode())]
    if zip_ is not None:
        assert staging is not None  # the route makes one for a zip
        src = staging / "class.zip"
        src.write_bytes(b64(zip_, "zip"))
        entries = unpack(src, staging, class_caps(settings), "zip")
        return [Handed(student, kind, _inside(name, entries), path=entries[name])
                for student, name, kind in group_names(list(entries))]  # fmt: skip
    out, seen = [], set()
    for i, s in enumerate(subs or []):
        name = student_name(s.student)
        if name in seen:
            raise Invalid.at(f"submissions[{i}].student", f"'{name}' appears twice")
        seen.add(name)
        if s.image is not None:
            data = b64(s.image, f"submissions[{i}].image")
            out.append(Handed(name, s.format, f"{name}.{s.format}", data))
        else:
            text = s.scene if isinstance(s.scene, str) else json.dumps(s.scene)
            out.append(Handed(name, "scene", f"{name}.json", text.encode()))
    if not out:
        raise Invalid.at("submissions", "no submissions")
    return out


def start(runs: GradeRuns, assignment: dict, handed: list[Handed]) -> dict:
    """A run of `assignment` over `handed` (422 with paths under `assignment` for a spec that is wrong)."""
    try:
        return runs.start(assignment, handed)
    except AssignmentError as e:
        raise Invalid([{"path": "assignment" + ("." + x["path"] if x["path"] else ""),
                        "message": x["message"]} for x in e.errors]) from None  # fmt: skip


def json_part(data: bytes | bytearray, max_depth: int, where: str = "assignment", what: str = "the assignment") -> dict:
    """An upload's `assignment` part (or another JSON part) -> its JSON object (422 at `where` when it is not one)."""
    depth = json_depth(bytes(data))
    if depth > max_depth:
        raise Invalid.at(where, f"JSON nested {depth} levels deep; at most {max_depth} (TRACER_MAX_JSON_DEPTH)")
    try:
        value = json.loads(bytes(data).decode("utf-8"))
    except UnicodeDecodeError:
        raise Invalid.at(where, "not UTF-8 text") from None
    except json.JSONDecodeError as e:
        raise Invalid.at(where, f"invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}") from None
    if not isinstance(value, dict):
        raise Invalid.at(where, f"{what} must be a JSON object {{...}}")
    return value


def with_reference(assignment: dict, reference: dict) -> dict:
    """The reference scene sent beside an assignment that names it as a file, put inline."""
    if not isinstance(assignment.get("reference"), dict):
        raise Invalid.at("reference", "the assignment has no 'reference' for it")
    assignment["reference"]["scene"] = reference
    return assignment


def unpacked(up: Upload, staging: Path, caps: Caps) -> list[Handed]:
    """The uploaded class -> one submission per student, its file on disk (a zip unpacked first)."""
    if up.zip is not None:
        entries = unpack(up.zip, staging, caps, "class")
    else:
        entries = {name.replace("\\", "/"): path for name, path in up.files if kept(name)}
        if not group_names(list(entries)):
            raise Invalid.at("files", NO_SUBMISSIONS)
    return [Handed(student, kind, name, path=entries[name]) for student, name, kind in group_names(list(entries))]


def unpack(src: Path, staging: Path, caps: Caps, where: str) -> dict[str, Path]:
    """A class's zip file -> its files in staging/class/ by relative path (422 at `where` naming the broken
    entry, or when it holds no submission); the zip itself is removed."""
    try:
        entries = unpack_zip(src, staging / "class", caps)
    except GradingError as e:
        raise Invalid.at(where, str(e)) from None
    src.unlink()
    if not group_names(list(entries)):
        raise Invalid.at(where, NO_SUBMISSIONS)
    return entries


def state(runs: GradeRuns, run_id: str) -> dict:
    """A run's state (404 for an unknown one)."""
    found = runs.state(run_id)
    if found is None:
        raise NotFound.at("id", f"no grading run with id '{run_id[:64]}'")
    return found


def public(found: dict, runs: GradeRuns) -> dict:
    """A run as the API shows it: its state, its url, and its reports once done."""
    out = dict(found)
    out["url"] = f"/api/grade/{found['id']}"
    out["reports"] = runs.reports(found["id"]) if found["status"] == JobStatus.done else []
    return out


def _folder(runs: GradeRuns, run_id: str) -> Path:
    """The folder of a run that state() has found."""
    folder = runs.folder(run_id)
    assert folder is not None
    return folder


def summary(runs: GradeRuns, run_id: str, fmt: str) -> bytes:
    """The class summary (summary.csv or summary.json) of a run that is done (404 before)."""
    found = state(runs, run_id)
    if found["status"] != JobStatus.done:
        raise NotFound(f"no summary yet: the run is {found['status']}")
    return (_folder(runs, run_id) / "out" / f"summary.{fmt}").read_bytes()


def student_file(runs: GradeRuns, run_id: str, student: str, file: str) -> Path:
    """One of a student's files (STUDENT_FILES) in a run (404 for another name, or one not written yet)."""
    state(runs, run_id)
    if file not in STUDENT_FILES or student != student_name(student):
        raise NotFound.at("file", f"one of: {', '.join(STUDENT_FILES)}")
    path = _folder(runs, run_id) / "out" / student / file
    if not path.is_file():
        raise NotFound.at("file", f"no {file} for '{student}' (yet)")
    return path
