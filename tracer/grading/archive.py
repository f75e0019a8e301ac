"""A class in a zip, read with bounds that hold whatever the archive claims.

A zip's headers declare each entry's size; a zip bomb lies (a header says 100 B, the entry inflates to
1 GiB of zeros) or tells the truth about something huge. So nothing here trusts a declared size:

- the number of entries is checked against `Caps.entries` before Python's zipfile reads the directory
  into memory (a ZipInfo per entry): first as the end of central directory record says it, then by
  counting the directory's entries as zipfile will walk them, header by header, stopping at the cap (an
  end record that says 1 of a million entries is refused after reading the cap's worth of headers);
- each entry is inflated as a stream, a chunk at a time, counting what comes out: past the size its
  header declares, past `Caps.file_bytes` (one file) or past `Caps.total_bytes` (all of them) it is
  refused at once, by name, having held at most one chunk more than the cap;
- its CRC-32 is checked against the header at its end; only stored and deflated entries are read
  (bzip2 and LZMA inflate in one unbounded step in Python's zipfile), encrypted ones are refused.

Every problem is a GradingError whose message starts with the entry's name (or says the file is not a
zip at all): the service answers it with a 422, the CLI prints it. Folders, hidden files, `__MACOSX`,
absolute paths, `..` and files that cannot be submissions (not .json, .png or .exr) are skipped unread.
"""

from __future__ import annotations

import copy
import io
import struct
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, BinaryIO

from tracer.grading.metrics import GradingError

MAX_FILE_BYTES = 20_000_000  # one submitted file, unpacked
MAX_ENTRIES = 5000  # entries of a zip (files and folders), or files of a class
MAX_CLASS_BYTES = 1_000_000_000  # all the files of a class, unpacked
CHUNK = 1 << 16  # bytes inflated at a time
SUFFIXES = {".json": "scene", ".png": "png", ".exr": "exr"}  # what a submission can be
METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate"}  # the compression methods read
# zipfile's own reader of the end record and its layout constants: not in typeshed's stubs (private), so Any
_zip: Any = zipfile


@dataclass(frozen=True)
class Caps:
    """How much of a class is read: `entries` (of a zip: files and folders; of a list of files: files),
    `total_bytes` (all the files unpacked), `file_bytes` (one of them). `entries_name` and `bytes_name`
    say where a cap was set, for the messages (the service: its settings' environment variables)."""

    entries: int = MAX_ENTRIES
    total_bytes: int = MAX_CLASS_BYTES
    file_bytes: int = MAX_FILE_BYTES
    entries_name: str = ""
    bytes_name: str = ""

    def too_many(self, n: int, what: str = "entries") -> GradingError:
        return GradingError(f"{n} {what}; at most {self.entries}{_named(self.entries_name)}")


def _named(name: str) -> str:
    return f" ({name})" if name else ""


def zip_name(info: zipfile.ZipInfo) -> str:
    """A member's name: zips without the UTF-8 flag are read as code page 437 (the zip standard), but
    many tools (macOS, Linux) write UTF-8 without setting it, so "Zoë.json" would come out "Zo├½.json"."""
    if info.flag_bits & 0x800:
        return info.filename
    try:
        return info.filename.encode("cp437").decode("utf-8")
    except UnicodeError:  # really code page 437 (or another one we cannot tell): as read
        return info.filename


def kept(name: str) -> bool:
    """Whether a file of a class is read: a possible submission, not hidden, inside the class."""
    p = PurePosixPath(name.replace("\\", "/"))
    hidden = any(s.startswith((".", "__MACOSX")) for s in p.parts)
    return not (p.is_absolute() or ".." in p.parts or hidden) and p.suffix.lower() in SUFFIXES


def open_zip(src: BinaryIO, caps: Caps) -> zipfile.ZipFile:
    """A zip file opened once its entry count is known to be within the cap (counted before Python reads
    the directory into memory: the end of central directory record's count, then the directory's own)."""
    try:
        end = _zip._EndRecData(src)  # the end record (zip64 too); None when there is none
    except OSError as e:
        raise GradingError(f"not a zip file: {e}") from None
    if end is None:
        raise GradingError("not a zip file (no end of central directory record)")
    count = end[_zip._ECD_ENTRIES_TOTAL]
    if count > caps.entries:
        raise caps.too_many(count)
    if directory_entries(src, end, caps.entries) > caps.entries:
        raise GradingError(f"more than {caps.entries} entries in its central directory (its end record says "
                           f"{count}); at most {caps.entries}{_named(caps.entries_name)}")  # fmt: skip
    try:
        return zipfile.ZipFile(src)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as e:
        raise GradingError(f"not a zip file: {e}") from None


def directory_entries(src: BinaryIO, end: list, most: int) -> int:
    """The entries of the central directory that zipfile would read (ZipFile._RealGetContents: from where
    the end record puts the directory, header after header for the directory's size in bytes), counted up
    to `most` + 1 without keeping any. A header that is cut short or not one ends the count (zipfile then
    says why the file is broken)."""
    size = end[_zip._ECD_SIZE]
    start = end[_zip._ECD_LOCATION] - size
    if end[_zip._ECD_SIGNATURE] == _zip.stringEndArchive64:
        start -= _zip.sizeEndCentDir64 + _zip.sizeEndCentDir64Locator
    if start < 0:
        return 0
    n, at = 0, 0
    while at < size and n <= most:
        src.seek(start + at)
        head = src.read(_zip.sizeCentralDir)
        if len(head) != _zip.sizeCentralDir or head[:4] != _zip.stringCentralDir:
            break
        fields = struct.unpack(_zip.structCentralDir, head)
        lengths = (_zip._CD_FILENAME_LENGTH, _zip._CD_EXTRA_FIELD_LENGTH, _zip._CD_COMMENT_LENGTH)
        at += _zip.sizeCentralDir + sum(fields[i] for i in lengths)
        n += 1
    return n


def members(zf: zipfile.ZipFile) -> list[tuple[str, zipfile.ZipInfo]]:
    """The entries that are read, by name (see `kept`), in the zip's order."""
    out = []
    for info in zf.infolist():
        name = zip_name(info)
        if not info.is_dir() and kept(name):
            out.append((str(PurePosixPath(name.replace("\\", "/"))), info))
    return out


def inflate(zf: zipfile.ZipFile, info: zipfile.ZipInfo, name: str, budget: int, caps: Caps) -> Iterator[bytes]:
    """An entry's bytes, a chunk at a time, bounded: at most `budget` (what is left of the class's
    total), `caps.file_bytes`, and the size its header declares; its CRC-32 checked at the end."""
    if info.flag_bits & 0x1:
        raise GradingError(f"{name}: is encrypted; give the class without a password")
    if info.compress_type not in METHODS:
        raise GradingError(f"{name}: compressed with method {info.compress_type}; only stored and deflate entries "
                           "are read (zip it again with the usual settings)")  # fmt: skip
    limit = min(caps.file_bytes, budget)
    if info.file_size > limit:
        raise _over(name, info.file_size, caps, budget)
    # zipfile stops at the declared size; we read on to see if the entry holds more (Any: typeshed's ZipInfo
    # allows no CRC of None)
    unbounded: Any = copy.copy(info)
    unbounded.file_size = info.file_size + 1
    unbounded.CRC = None  # and check the CRC ourselves (zipfile would check it against a cut-short stream)
    crc, n = 0, 0
    try:
        with zf.open(unbounded) as f:
            while chunk := f.read(CHUNK):
                n += len(chunk)
                if n > info.file_size:
                    raise GradingError(f"{name}: holds more than the {info.file_size} bytes its header declares")
                crc = zlib.crc32(chunk, crc)
                yield chunk
    except GradingError:
        raise
    except Exception as e:  # zlib.error, BadZipFile, EOFError, OSError...: a broken entry, never a crash
        raise GradingError(f"{name}: cannot unpack it ({type(e).__name__}: {e})") from None
    if n != info.file_size:
        raise GradingError(f"{name}: holds {n} bytes; its header declares {info.file_size} (a broken zip)")
    if crc != info.CRC:
        raise GradingError(f"{name}: bad CRC-32 (the entry is corrupt)")


def _over(name: str, size: int, caps: Caps, budget: int) -> GradingError:
    if size > caps.file_bytes:
        return GradingError(f"{name}: unpacks to {size} bytes; at most {caps.file_bytes} per file")
    return GradingError(f"{name}: the class unpacks to more than {caps.total_bytes} bytes{_named(caps.bytes_name)}")


def read_zip(data: bytes | BinaryIO, caps: Caps = Caps()) -> dict[str, bytes]:
    """The files of a zip (its bytes or an open file) that may be submissions, by relative path."""
    src = io.BytesIO(data) if isinstance(data, bytes | bytearray) else data
    out: dict[str, bytes] = {}
    left = caps.total_bytes
    with open_zip(src, caps) as zf:
        for name, info in members(zf):
            out[name] = b"".join(inflate(zf, info, name, left, caps))
            left -= len(out[name])
    return out


def unpack_zip(src: Path | BinaryIO, dest: Path, caps: Caps = Caps()) -> dict[str, Path]:
    """The files of a zip that may be submissions, written to `dest` (one file each, named by its number
    and suffix, never by the zip's names), by relative path. Never holds more than a chunk in memory."""
    dest.mkdir(parents=True, exist_ok=True)
    out: dict[str, Path] = {}
    left = caps.total_bytes
    with open(src, "rb") if isinstance(src, Path) else _borrowed(src) as f, open_zip(f, caps) as zf:
        for i, (name, info) in enumerate(members(zf)):
            path = dest / f"{i:05d}{PurePosixPath(name).suffix.lower()}"
            with open(path, "wb") as w:
                for chunk in inflate(zf, info, name, left, caps):
                    w.write(chunk)
                    left -= len(chunk)
            out[name] = path
    return out


class _borrowed:
    """A file the caller keeps open: `with` leaves it open."""

    def __init__(self, f: BinaryIO):
        self.f = f

    def __enter__(self) -> BinaryIO:
        return self.f

    def __exit__(self, *exc) -> None:
        pass
