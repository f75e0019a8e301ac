"""Grading: an instructor posts an assignment and submissions (a scene, an image, a list, or a zip);
the renders go through the job queue; the run's state, reports and pictures are read back. Every route
here is the instructor's (server/core/security.py): 401 without TRACER_INSTRUCTOR_TOKEN when the server has one."""

from __future__ import annotations

import base64
import binascii
import json
import shutil
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Request, Response
from pydantic import BaseModel, ConfigDict, Field, model_validator
from starlette.concurrency import run_in_threadpool

from server.api.deps import RunsDep, SettingsDep, require_instructor
from server.api.errors import ApiError
from server.api.gate import json_depth
from server.api.models import ErrorResponse, HandedIn
from server.core.paths import ROOT
from server.core.settings import Settings
from server.grading.runs import STUDENT_FILES, GradeRuns, Handed
from server.grading.uploads import Upload, receive
from server.jobs.lifecycle import JobStatus
from tracer.grading import (
    AssignmentError,
    Caps,
    GradingError,
    group_names,
    student_for_file,
    student_name,
    unpack_zip,
)
from tracer.grading.archive import kept
from tracer.grading.batch import MAX_FILES, _inside

INSTRUCTOR = {
    401: {"model": ErrorResponse, "description": "no instructor token, or not the instructor's (WWW-Authenticate)"},
    403: {"model": ErrorResponse, "description": "this server has no instructor (not loopback, no instructor token)"},
}
router = APIRouter(
    prefix="/api/grade", tags=["grading"], dependencies=[Depends(require_instructor)], responses=INSTRUCTOR
)
ERRORS = {422: {"model": ErrorResponse, "description": "invalid assignment or submission, with JSON paths"}}
NOT_FOUND = {404: {"model": ErrorResponse, "description": "no such grading run"}}
NO_SUBMISSIONS = "no submissions in it (.json, .png or .exr files)"
EXAMPLE = "scenes/grading"  # the example assignment and class, for the page's "Load the example"
UPLOAD = "/api/grade/upload"  # streamed (server/grading/uploads.py): the request gate does not buffer it
UPLOAD_BODY = {  # the multipart body, for /docs (the route parses it as a stream, not through FastAPI's models)
    "requestBody": {"required": True, "content": {"multipart/form-data": {"schema": {
        "type": "object", "required": ["assignment"],
        "properties": {
            "assignment": {"type": "string", "description": "the assignment's JSON (its reference scene inline)"},
            "class": {"type": "string", "format": "binary", "description": "the class as one zip (docs/grading.md)"},
            "files": {"type": "array", "items": {"type": "string", "format": "binary"},
                      "description": "or one part per submission (.json, .png, .exr), named by its file name"},
        },
    }}}},
}  # fmt: skip


class SubmissionIn(HandedIn):
    """One student's work in a class graded at once."""

    student: str = Field(min_length=1, max_length=80, description="the student's name or id")


class GradeCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    assignment: dict[str, Any] = Field(description="the assignment spec (docs/grading.md); its reference inline")
    scene: dict[str, Any] | str | None = Field(None, description="one scene to grade")
    submissions: list[SubmissionIn] | None = Field(None, description="a class: one entry per student")
    zip: str | None = Field(None, description="a class as a zip file, base64 (layout: docs/grading.md)")

    @model_validator(mode="after")
    def _one(self) -> GradeCreate:
        if sum(x is not None for x in (self.scene, self.submissions, self.zip)) != 1:
            raise ValueError("give exactly one of 'scene', 'submissions' and 'zip'")
        return self


class StudentsIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    files: list[Annotated[str, Field(max_length=1000)]] = Field(
        max_length=MAX_FILES, description='file names, as the instructor picked them ("Zoë O\'Brien.json")'
    )


def _b64(text: str, where: str) -> bytes:
    try:
        return base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise ApiError(422, [{"path": where, "message": "expected base64 data"}]) from None


def class_caps(settings: Settings) -> Caps:
    """How much of a class the service reads (docs/grading.md): the settings' caps."""
    return Caps(
        entries=settings.max_class_entries, total_bytes=int(settings.max_class_bytes),
        entries_name="TRACER_MAX_CLASS_ENTRIES", bytes_name="TRACER_MAX_CLASS_BYTES",
    )  # fmt: skip


def _submissions(body: GradeCreate, settings: Settings, staging: Path | None) -> list[Handed]:
    """The body's submissions; a zip is unpacked into `staging` (a folder of the run's disk) with the same
    bounded reader as an upload's: never more than a chunk of it in memory, whatever its headers say."""
    if body.scene is not None:
        text = body.scene if isinstance(body.scene, str) else json.dumps(body.scene)
        return [Handed("submission", "scene", "submission.json", text.encode())]
    if body.zip is not None:
        src = staging / "class.zip"
        src.write_bytes(_b64(body.zip, "zip"))
        entries = _unpack(src, staging, class_caps(settings), "zip")
        return [Handed(student, kind, _inside(name, entries), path=entries[name])
                for student, name, kind in group_names(list(entries))]  # fmt: skip
    out, seen = [], set()
    for i, s in enumerate(body.submissions or []):
        name = student_name(s.student)
        if name in seen:
            raise ApiError(422, [{"path": f"submissions[{i}].student", "message": f"'{name}' appears twice"}])
        seen.add(name)
        if s.image is not None:
            data = _b64(s.image, f"submissions[{i}].image")
            out.append(Handed(name, s.format, f"{name}.{s.format}", data))
        else:
            text = s.scene if isinstance(s.scene, str) else json.dumps(s.scene)
            out.append(Handed(name, "scene", f"{name}.json", text.encode()))
    if not out:
        raise ApiError(422, [{"path": "submissions", "message": "no submissions"}])
    return out


def _public(state: dict, runs: GradeRuns) -> dict:
    out = dict(state)
    out["url"] = f"/api/grade/{state['id']}"
    out["reports"] = runs.reports(state["id"]) if state["status"] == JobStatus.done else []
    return out


@router.post("", status_code=202, summary="Grade a scene, an image or a class", responses=ERRORS)
def grade(body: GradeCreate, runs: RunsDep, settings: SettingsDep, response: Response) -> dict:
    """Validate the assignment (422 with paths under `assignment`), start the run (202): its renders
    are queued jobs with the assignment's time limit each. Follow it at `url` until `status` is done.
    A class of any size: POST /api/grade/upload (multipart, streamed); this JSON body has the request
    size limit (TRACER_MAX_BODY_BYTES)."""
    staging = runs.staging() if body.zip is not None else None
    try:
        state = start_run(runs, body.assignment, _submissions(body, settings, staging))
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
    response.headers["Location"] = f"/api/grade/{state['id']}"
    return _public(state, runs)


def start_run(runs: GradeRuns, assignment: dict, handed: list[Handed]) -> dict:
    try:
        return runs.start(assignment, handed)
    except AssignmentError as e:
        raise ApiError(422, [{"path": "assignment" + ("." + x["path"] if x["path"] else ""),
                              "message": x["message"]} for x in e.errors]) from None  # fmt: skip


@router.post(
    "/upload", status_code=202, summary="Grade a class uploaded as a zip or as files (multipart, streamed)",
    responses={**ERRORS, 413: {"model": ErrorResponse, "description": "past a cap on the class's size"},
               415: {"model": ErrorResponse, "description": "not multipart/form-data"}},
    openapi_extra=UPLOAD_BODY,
)  # fmt: skip
async def upload(request: Request, runs: RunsDep, settings: SettingsDep, response: Response) -> dict:
    """multipart/form-data: an `assignment` part (its JSON, the reference scene inline, or named as a file and
    sent as a `reference` part beside it) and the class as
    one `class` part (a zip, laid out as docs/grading.md says) or as `files` parts (one per submission,
    named by its file name). Read as a stream into files, never whole into memory; the class may have
    at most TRACER_MAX_CLASS_ENTRIES entries and TRACER_MAX_CLASS_BYTES unpacked, each file 20 MB (422
    naming the entry past a cap, or a broken one). Then as POST /api/grade: 202 with the run."""
    caps = class_caps(settings)
    staging = runs.staging()
    try:
        kind = request.headers.get("content-type", "")
        up = await receive(kind, request.stream(), staging, caps, settings.max_body_bytes)
        assignment = _assignment(up.assignment, settings)
        if up.reference is not None:  # the reference scene beside an assignment that names it as a file
            reference = _assignment(up.reference, settings, "reference", "the reference scene")
            if not isinstance(assignment.get("reference"), dict):
                raise ApiError(422, [{"path": "reference", "message": "the assignment has no 'reference' for it"}])
            assignment["reference"]["scene"] = reference
        handed = await run_in_threadpool(_unpacked, up, staging, caps)
        state = await run_in_threadpool(start_run, runs, assignment, handed)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    response.headers["Location"] = f"/api/grade/{state['id']}"
    return _public(state, runs)


def _assignment(data: bytes, settings: Settings, where: str = "assignment", what: str = "the assignment") -> dict:
    """The `assignment` part (or another JSON part) -> its JSON object (422 at `where` when it is not one)."""
    depth = json_depth(bytes(data))
    if depth > settings.max_json_depth:
        message = f"JSON nested {depth} levels deep; at most {settings.max_json_depth} (TRACER_MAX_JSON_DEPTH)"
        raise ApiError(422, [{"path": where, "message": message}])
    try:
        value = json.loads(bytes(data).decode("utf-8"))
    except UnicodeDecodeError:
        raise ApiError(422, [{"path": where, "message": "not UTF-8 text"}]) from None
    except json.JSONDecodeError as e:
        message = f"invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}"
        raise ApiError(422, [{"path": where, "message": message}]) from None
    if not isinstance(value, dict):
        raise ApiError(422, [{"path": where, "message": f"{what} must be a JSON object {{...}}"}])
    return value


def _unpacked(up: Upload, staging: Path, caps: Caps) -> list[Handed]:
    """The uploaded class -> one submission per student, its file on disk (a zip unpacked first)."""
    if up.zip is not None:
        entries = _unpack(up.zip, staging, caps, "class")
    else:
        entries = {name.replace("\\", "/"): path for name, path in up.files if kept(name)}
        if not group_names(list(entries)):
            raise ApiError(422, [{"path": "files", "message": NO_SUBMISSIONS}])
    return [Handed(student, kind, name, path=entries[name]) for student, name, kind in group_names(list(entries))]


def _unpack(src: Path, staging: Path, caps: Caps, where: str) -> dict[str, Path]:
    """A class's zip file -> its files in staging/class/ by relative path (422 at `where` naming the broken
    entry, or when it holds no submission); the zip itself is removed."""
    try:
        entries = unpack_zip(src, staging / "class", caps)
    except GradingError as e:
        raise ApiError(422, [{"path": where, "message": str(e)}]) from None
    src.unlink()
    if not group_names(list(entries)):
        raise ApiError(422, [{"path": where, "message": NO_SUBMISSIONS}])
    return entries


@router.get("/schema", summary="The JSON Schema of an assignment")
def schema() -> dict:
    """Generated from the same models that validate assignments (tracer/grading/spec.py)."""
    from tracer.grading import Assignment

    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **Assignment.model_json_schema()}


@router.post("/students", summary="The student each file name stands for")
def students(body: StudentsIn) -> dict:
    """{"files": ["Zoë O'Brien.json", "bob.png"]} -> {"students": ["Zoë_O_Brien", "bob"]}: the student ids
    the grader will use (the name without its suffix; Unicode letters, marks and digits, '.', '_', '-';
    other characters become '_'). The page names picked files by this, so it never keeps a copy of the rule."""
    return {"students": [student_for_file(name) for name in body.files]}


@router.get("/example", summary="The example assignment (reference inline) and class")
def example() -> dict:
    """What the page's "Load the example" fills in: scenes/grading/assignment.json with its reference
    scene inline, and the example class (scenes as text, images as base64)."""
    from tracer.grading import collect

    root = ROOT / EXAMPLE
    assignment = json.loads((root / "assignment.json").read_text())
    assignment["reference"]["scene"] = json.loads((root / assignment["reference"]["scene"]).read_text())
    subs = []
    for s in collect(root / "class"):
        if s.kind == "scene":
            subs.append({"student": s.student, "scene": s.data.decode("utf-8", errors="replace")})
        else:
            subs.append({"student": s.student, "image": base64.b64encode(s.data).decode(), "format": s.kind})
    return {"assignment": assignment, "submissions": subs}


def _run(run_id: str, runs: GradeRuns) -> dict:
    state = runs.state(run_id)
    if state is None:
        raise ApiError(404, [{"path": "id", "message": f"no grading run with id '{run_id[:64]}'"}])
    return state


@router.get("/{run_id}", summary="A grading run: status, render progress, summary and reports", responses=NOT_FOUND)
def run_state(run_id: str, runs: RunsDep) -> dict:
    return _public(_run(run_id, runs), runs)


@router.get("/{run_id}/summary.{fmt}", summary="The class summary as CSV or JSON", responses=NOT_FOUND)
def run_summary(run_id: str, fmt: Literal["csv", "json"], runs: RunsDep) -> Response:
    state = _run(run_id, runs)
    if state["status"] != JobStatus.done:
        raise ApiError(404, f"no summary yet: the run is {state['status']}")
    data = (runs.folder(run_id) / "out" / f"summary.{fmt}").read_bytes()
    media = "text/csv" if fmt == "csv" else "application/json"
    return Response(data, media_type=media, headers={"Content-Disposition": f'inline; filename="summary.{fmt}"'})


@router.get("/{run_id}/students/{student}/{file}", summary="A student's report, results.json or picture",
            responses=NOT_FOUND)  # fmt: skip
def student_file(run_id: str, student: str, file: str, runs: RunsDep) -> Response:
    """render.png (their scene, as we rendered it, or their image), reference.png, error_map.png (FLIP),
    rejected.png (pixels the z test rejected), results.json (Gradescope), report.json."""
    _run(run_id, runs)
    if file not in STUDENT_FILES or student != student_name(student):
        raise ApiError(404, [{"path": "file", "message": f"one of: {', '.join(STUDENT_FILES)}"}])
    path = runs.folder(run_id) / "out" / student / file
    if not path.is_file():
        raise ApiError(404, [{"path": "file", "message": f"no {file} for '{student}' (yet)"}])
    return Response(path.read_bytes(), media_type=STUDENT_FILES[file], headers={"Cache-Control": "no-store"})
