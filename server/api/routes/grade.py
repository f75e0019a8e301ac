"""Grading: an instructor posts an assignment and submissions (a scene, an image, a list, or a zip);
the renders go through the job queue; the run's state, reports and pictures are read back. Every route
here is the instructor's (server/core/security.py): 401 without TRACER_INSTRUCTOR_TOKEN when the server has one.
The rules (what a class may be, its checks and their refusals) live in server/grading/handin.py: these routes
translate HTTP."""

from __future__ import annotations

import base64
import json
import shutil
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Request, Response
from pydantic import BaseModel, ConfigDict, Field, model_validator
from starlette.concurrency import run_in_threadpool

from server.api.deps import RunsDep, SettingsDep, require_instructor
from server.api.models import ErrorResponse, HandedIn, Responses
from server.core.paths import ROOT
from server.grading import handin
from server.grading.runs import STUDENT_FILES
from server.grading.uploads import receive
from tracer.grading import student_for_file
from tracer.grading.batch import MAX_FILES

INSTRUCTOR: Responses = {
    401: {"model": ErrorResponse, "description": "no instructor token, or not the instructor's (WWW-Authenticate)"},
    403: {"model": ErrorResponse, "description": "this server has no instructor (not loopback, no instructor token)"},
}
router = APIRouter(
    prefix="/api/grade", tags=["grading"], dependencies=[Depends(require_instructor)], responses=INSTRUCTOR
)
ERRORS: Responses = {422: {"model": ErrorResponse, "description": "invalid assignment or submission, with JSON paths"}}
NOT_FOUND: Responses = {404: {"model": ErrorResponse, "description": "no such grading run"}}
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


@router.post("", status_code=202, summary="Grade a scene, an image or a class", responses=ERRORS)
def grade(body: GradeCreate, runs: RunsDep, settings: SettingsDep, response: Response) -> dict:
    """Validate the assignment (422 with paths under `assignment`), start the run (202): its renders
    are queued jobs with the assignment's time limit each. Follow it at `url` until `status` is done.
    A class of any size: POST /api/grade/upload (multipart, streamed); this JSON body has the request
    size limit (TRACER_MAX_BODY_BYTES)."""
    staging = runs.staging() if body.zip is not None else None
    try:
        handed = handin.submissions(body.scene, body.submissions, body.zip, settings, staging)
        state = handin.start(runs, body.assignment, handed)
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
    response.headers["Location"] = f"/api/grade/{state['id']}"
    return handin.public(state, runs)


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
    caps = handin.class_caps(settings)
    staging = runs.staging()
    try:
        kind = request.headers.get("content-type", "")
        up = await receive(kind, request.stream(), staging, caps, settings.max_body_bytes)
        assignment = handin.json_part(up.assignment, settings.max_json_depth)
        if up.reference is not None:  # the reference scene beside an assignment that names it as a file
            reference = handin.json_part(up.reference, settings.max_json_depth, "reference", "the reference scene")
            handin.with_reference(assignment, reference)
        handed = await run_in_threadpool(handin.unpacked, up, staging, caps)
        state = await run_in_threadpool(handin.start, runs, assignment, handed)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    response.headers["Location"] = f"/api/grade/{state['id']}"
    return handin.public(state, runs)


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


@router.get("/{run_id}", summary="A grading run: status, render progress, summary and reports", responses=NOT_FOUND)
def run_state(run_id: str, runs: RunsDep) -> dict:
    return handin.public(handin.state(runs, run_id), runs)


@router.get("/{run_id}/summary.{fmt}", summary="The class summary as CSV or JSON", responses=NOT_FOUND)
def run_summary(run_id: str, fmt: Literal["csv", "json"], runs: RunsDep) -> Response:
    data = handin.summary(runs, run_id, fmt)
    media = "text/csv" if fmt == "csv" else "application/json"
    return Response(data, media_type=media, headers={"Content-Disposition": f'inline; filename="summary.{fmt}"'})


@router.get("/{run_id}/students/{student}/{file}", summary="A student's report, results.json or picture",
            responses=NOT_FOUND)  # fmt: skip
def student_file(run_id: str, student: str, file: str, runs: RunsDep) -> Response:
    """render.png (their scene, as we rendered it, or their image), reference.png, error_map.png (FLIP),
    rejected.png (pixels the z test rejected), results.json (Gradescope), report.json."""
    path = handin.student_file(runs, run_id, student, file)
    return Response(path.read_bytes(), media_type=STUDENT_FILES[file], headers={"Cache-Control": "no-store"})
