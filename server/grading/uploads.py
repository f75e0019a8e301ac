"""A class uploaded as multipart/form-data (POST /api/grade/upload): parsed as it arrives and written to
files, never held whole in memory.

The parts:
- `assignment`: the assignment's JSON, as a text field or a file; at most TRACER_MAX_BODY_BYTES;
- `reference` (optional): the reference scene's JSON, when the assignment names it as a file
  (`scenes/grading/assignment.json` with `reference.json` beside it); at most TRACER_MAX_BODY_BYTES;
- `class`: the whole class as one zip file, unpacked afterwards with the caps (tracer/grading/archive.py);
- or `files`: one part per submitted file (a scene .json, an image .png or .exr), its student named by
  its file name as in a zip ("carol/scene.json" puts it in carol's folder).

Each file part goes straight to a file in the upload's staging folder (on the data directory's disk,
so the run can take the files by renaming them), counted as it is written: the `files` parts against
TRACER_MAX_CLASS_ENTRIES and TRACER_MAX_CLASS_BYTES, each one against the per-file cap. The request as
a whole is bounded before it is read by the request gate (server/api/gate.py).
"""

from __future__ import annotations

import re
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO
from urllib.parse import unquote

from python_multipart.exceptions import FormParserError
from python_multipart.multipart import MultipartParser, parse_options_header

if TYPE_CHECKING:
    from python_multipart.multipart import MultipartCallbacks

from server.core.errors import DomainError, Invalid, TooLarge, Unsupported
from tracer.grading import Caps

PARTS = ("assignment", "reference", "class", "files")
_STAR = re.compile(rb"filename\*\s*=\s*([\w!#$%&+.^`|~-]*)'[^']*'([^;\s]+)", re.IGNORECASE)
_HTML5 = {"%22": '"', "%0A": "\n", "%0D": "\r"}  # how browsers escape these in a form's file names


@dataclass
class Upload:
    """What a multipart body held: the assignment's bytes, and the class as a zip or as files."""

    assignment: bytearray = field(default_factory=bytearray)
    reference: bytearray | None = None  # the reference scene, when it came as its own part
    zip: Path | None = None
    files: list[tuple[str, Path]] = field(default_factory=list)  # (the file's name as sent, where it is)
    seen: set[str] = field(default_factory=set)  # the parts given


def _refuse(path: str, message: str, kind: type[DomainError] = Invalid) -> DomainError:
    return kind.at(path, message)


def _filename(disposition: bytes, options: dict) -> str | None:
    star = _STAR.search(disposition)
    if star:  # RFC 5987: filename*=UTF-8''Zo%C3%AB.json
        charset = star[1].decode("ascii", "replace") or "utf-8"
        try:
            return unquote(star[2].decode("ascii", "replace"), encoding=charset, errors="replace")
        except LookupError:
            return unquote(star[2].decode("ascii", "replace"))
    if b"filename" not in options:
        return None
    name = options[b"filename"].decode("utf-8", errors="replace")
    for code, char in _HTML5.items():
        name = name.replace(code, char)
    return name


class _Parts:
    """python-multipart's callbacks: each part's headers, then its data to memory (the assignment) or a file."""

    def __init__(self, staging: Path, caps: Caps, max_assignment: int):
        self.staging, self.caps, self.max_assignment = staging, caps, max_assignment
        self.upload = Upload()
        self.headers: dict[bytes, bytes] = {}
        self.field, self.value = b"", b""
        self.name = ""  # the current part's name
        self.out: BinaryIO | None = None  # where its data goes (None: the assignment, in memory)
        self.size = 0  # bytes of the current part
        self.total = 0  # bytes of all the `files` parts

    def callbacks(self) -> MultipartCallbacks:
        return {
            "on_part_begin": self.begin, "on_part_data": self.data, "on_part_end": self.end,
            "on_header_field": self.header_field, "on_header_value": self.header_value,
            "on_header_end": self.header_end, "on_headers_finished": self.headers_finished,
        }  # fmt: skip

    def begin(self) -> None:
        self.headers, self.size, self.out = {}, 0, None

    def header_field(self, data: bytes, start: int, end: int) -> None:
        self.field += data[start:end]

    def header_value(self, data: bytes, start: int, end: int) -> None:
        self.value += data[start:end]

    def header_end(self) -> None:
        self.headers[self.field.lower()] = self.value
        self.field, self.value = b"", b""

    def headers_finished(self) -> None:
        disposition = self.headers.get(b"content-disposition", b"")
        _, options = parse_options_header(disposition)
        self.name = options.get(b"name", b"").decode("utf-8", errors="replace")
        filename = _filename(disposition, options)
        up = self.upload
        if self.name not in PARTS:
            raise _refuse(self.name or "", f"unknown part '{self.name[:80]}'; the parts: assignment (and "
                                           "reference), then class (a zip) or files (one per submission)")  # fmt: skip
        if self.name in ("assignment", "reference", "class") and self.name in up.seen:
            raise _refuse(self.name, f"give one '{self.name}' part")
        up.seen.add(self.name)
        if self.name == "reference":
            up.reference = bytearray()
        elif self.name == "class":
            up.zip = self.staging / "class.zip"
            self.out = open(up.zip, "wb")  # noqa: SIM115 (closed at the part's end, or by close())
        elif self.name == "files":
            if not filename:
                raise _refuse("files", "each 'files' part needs its file's name (it names the student)")
            if len(up.files) >= self.caps.entries:
                raise _refuse("files", f"more than {self.caps.entries} files; at most {self.caps.entries} "
                                       "(TRACER_MAX_CLASS_ENTRIES)")  # fmt: skip
            path = self.staging / f"part-{len(up.files):05d}"
            up.files.append((filename, path))
            self.out = open(path, "wb")  # noqa: SIM115

    def data(self, data: bytes, start: int, end: int) -> None:
        n = end - start
        self.size += n
        if self.out is None:
            if self.size > self.max_assignment:
                raise _refuse(self.name, f"larger than {self.max_assignment} bytes (TRACER_MAX_BODY_BYTES)", TooLarge)
            held = self.upload.reference if self.name == "reference" else self.upload.assignment
            assert held is not None  # the reference part's bytearray is made at its headers
            held += data[start:end]
            return
        if self.name == "files":
            self.total += n
            name = self.upload.files[-1][0]
            if self.size > self.caps.file_bytes:
                raise _refuse("files", f"{name}: larger than {self.caps.file_bytes} bytes")
            if self.total > self.caps.total_bytes:
                raise _refuse("files", f"{name}: the files are more than {self.caps.total_bytes} bytes together "
                                       "(TRACER_MAX_CLASS_BYTES)")  # fmt: skip
        self.out.write(memoryview(data)[start:end])  # no copy of the chunk

    def end(self) -> None:
        if self.out is not None:
            self.out.close()
            self.out = None

    def close(self) -> None:
        self.end()


async def receive(
    content_type: str, body: AsyncIterator[bytes], staging: Path, caps: Caps, max_assignment: int
) -> Upload:
    """Parse a multipart body (its Content-Type header, its chunks as they arrive), its files into `staging`
    (which must exist)."""
    kind, params = parse_options_header(content_type)
    if kind != b"multipart/form-data" or b"boundary" not in params:
        raise _refuse("", "expected a multipart/form-data body (parts: assignment, then class or files)", Unsupported)
    parts = _Parts(staging, caps, max_assignment)
    try:
        parser = MultipartParser(params[b"boundary"], parts.callbacks())
        async for chunk in body:
            parser.write(chunk)
        parser.finalize()
    except FormParserError as e:
        raise _refuse("", f"a broken multipart body: {e}") from None
    finally:
        parts.close()
    up = parts.upload
    if "assignment" not in up.seen:
        raise _refuse("assignment", "the 'assignment' part (the assignment's JSON) is missing")
    if "class" in up.seen and "files" in up.seen:
        raise _refuse("class", "give the class as one 'class' part (a zip) or as 'files' parts, not both")
    if "class" not in up.seen and "files" not in up.seen:
        raise _refuse("class", "the class is missing: a 'class' part (a zip) or 'files' parts")
    return up
