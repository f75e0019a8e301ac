"""A class uploaded as a stream (POST /api/grade/upload) and zips read with bounds (tracer/grading/archive.py).

Zips are made here: with Python's zipfile for the ordinary ones, and byte by byte (`raw_zip`) for the
hostile ones, whose headers lie: a zip bomb that declares 100 B and inflates to 1 GiB of zeros, an
entry whose CRC is wrong, deflate data that is garbage, a compression method we do not read. Every one
is refused with a 422 that names the entry, never a 500, never holding more than the caps in memory.
The service's tests use the app in a TestClient with real render workers (test_api_support.api_client)."""

from __future__ import annotations

import base64
import io
import json
import struct
import tracemalloc
import zipfile
import zlib
from pathlib import Path

import pytest

from server.jobs.files import JobFile
from tests.support.api import api_client, wait_for
from tests.support.grading_upload import CLASS, assignment_text, class_zip
from tests.support.scene import ROOT
from tracer.grading import Caps, GradingError, read_zip, unpack_zip
from tracer.grading.archive import CHUNK

EXPECTED = {  # the example class's scores and statuses (every test: tests/tracer/grading/test_grading.py)
    "alice": (13.0, "graded"), "bob": (6.0, "graded"), "carol": (0.0, "invalid"), "dave": (13.0, "graded"),
    "erin": (7.0, "graded"), "frank": (0.0, "invalid"), "grace": (7.0, "graded"), "heidi": (1.0, "graded"),
    "ivan": (0.0, "invalid"),
}  # fmt: skip
GiB = 1 << 30


def raw_zip(entries: list[dict]) -> bytes:
    """A zip written byte by byte, each entry's header saying what it is told to (dicts: name, data: the
    stored bytes, and optionally method 8 (deflate) or 0, crc, size: the declared uncompressed size,
    flags), whatever the data holds."""
    out, central = io.BytesIO(), io.BytesIO()
    for e in entries:
        name, data = e["name"].encode(), e["data"]
        method, crc, size, flags = e.get("method", 8), e.get("crc", 0), e.get("size", 0), e.get("flags", 0x800)
        offset = out.tell()
        out.write(struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, flags, method, 0, 0x21, crc, len(data), size,
                              len(name), 0) + name + data)  # fmt: skip
        central.write(struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, flags, method, 0, 0x21, crc, len(data),
                                  size, len(name), 0, 0, 0, 0, 0, offset) + name)  # fmt: skip
    start, cd = out.tell(), central.getvalue()
    out.write(cd + struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries), len(cd), start, 0))
    return out.getvalue()


def lying_zip(data: bytes, says: int = 1, zip64: bool = False) -> bytes:
    """A zip (written by zipfile, without a comment) whose end of central directory record says it holds
    `says` entries, whatever its directory holds; with `zip64`, the count is in a zip64 end record (and its
    locator) put before it, as zipfile reads for more than 65535 entries."""
    end = len(data) - zipfile.sizeEndCentDir
    sig, disk, first, _, _, size, offset, comment = struct.unpack(zipfile.structEndArchive, data[end:])
    if not zip64:
        return data[:end] + struct.pack(zipfile.structEndArchive, sig, disk, first, says, says, size, offset, comment)
    record = struct.pack(zipfile.structEndArchive64, zipfile.stringEndArchive64, 44, 45, 45, 0, 0, says, says,
                         size, offset)  # fmt: skip
    locator = struct.pack(zipfile.structEndArchive64Locator, zipfile.stringEndArchive64Locator, 0, end, 1)
    end64 = struct.pack(zipfile.structEndArchive, sig, 0, 0, 0xFFFF, 0xFFFF, 0xFFFFFFFF, 0xFFFFFFFF, 0)
    return data[:end] + record + locator + end64


def many_entries(n: int) -> bytes:
    """A zip of n stored scenes s0.json ... '{}'."""
    return raw_zip([{"name": f"s{i}.json", "data": b"{}", "method": 0, "size": 2, "crc": zlib.crc32(b"{}")}
                    for i in range(n)])  # fmt: skip


def deflated(data: bytes) -> bytes:
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    return c.compress(data) + c.flush()


@pytest.fixture(scope="module")
def bomb() -> bytes:
    """A zip bomb: 'bomb.json' declares 100 bytes (and the CRC of 100 zero bytes) and holds 1 GiB of zeros,
    deflated to about 1 MB."""
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    zeros = bytes(1 << 24)
    data = b"".join(c.compress(zeros) for _ in range(GiB // len(zeros))) + c.flush()
    return raw_zip([{"name": "hw4/bomb.json", "data": data, "size": 100, "crc": zlib.crc32(bytes(100))}])


# ------------------------------------------------------------------------------ the bounded zip reader


def test_archive_a_zip_bomb_is_refused_by_name_holding_one_chunk(bomb, tmp_path):
    """The header's 100 bytes are not trusted: the entry is inflated a chunk at a time and refused as soon
    as it holds more, with at most a chunk or two in memory (tracemalloc: Python's allocations; zlib's own
    window is a fixed 32 KB). The zip is read from a file, as an upload is."""
    assert len(bomb) < 1_100_000
    (tmp_path / "bomb.zip").write_bytes(bomb)
    tracemalloc.start()
    try:
        with pytest.raises(GradingError) as e:
            unpack_zip(tmp_path / "bomb.zip", tmp_path / "out", Caps())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert str(e.value) == "hw4/bomb.json: holds more than the 100 bytes its header declares"
    assert peak < 8 * CHUNK, peak  # 512 KB: never the gigabyte, nor the megabyte of the zip
    assert sum(f.stat().st_size for f in (tmp_path / "out").iterdir()) <= 100


def test_archive_caps_on_size_and_entries_are_checked_before_reading():
    big = raw_zip([{"name": "big.exr", "data": deflated(bytes(1000)), "size": 30_000_000, "crc": 0}])
    with pytest.raises(GradingError, match=r"^big.exr: unpacks to 30000000 bytes; at most 20000000 per file$"):
        read_zip(big)  # told by its header: not even opened
    many = io.BytesIO()
    with zipfile.ZipFile(many, "w") as z:
        for i in range(6):
            z.writestr(f"s{i}.json", "{}")
    caps = Caps(
        entries=5, total_bytes=1000, entries_name="TRACER_MAX_CLASS_ENTRIES", bytes_name="TRACER_MAX_CLASS_BYTES"
    )
    with pytest.raises(GradingError, match=r"^6 entries; at most 5 \(TRACER_MAX_CLASS_ENTRIES\)$"):
        read_zip(many.getvalue(), caps)
    total = io.BytesIO()
    with zipfile.ZipFile(total, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("a.json", "b.json", "c.json"):
            z.writestr(name, " " * 400)
    with pytest.raises(GradingError, match=r"^c.json: the class unpacks to more than 1000 bytes \(TRACER_MAX_CLASS"):
        read_zip(total.getvalue(), caps)


@pytest.mark.parametrize("zip64", [False, True], ids=["end-record", "zip64-end-record"])
def test_archive_entries_are_counted_in_the_directory_whatever_the_end_record_says(zip64):
    """A zip of 20 entries whose end record (or zip64 end record) says 1: its directory's headers are counted
    as zipfile would read them, and the count stops past the cap, before zipfile makes a ZipInfo of each."""
    honest = many_entries(20)
    lying = lying_zip(honest, zip64=zip64)
    assert zipfile._EndRecData(io.BytesIO(lying))[zipfile._ECD_ENTRIES_TOTAL] == 1
    assert len(read_zip(lying)) == 20  # zipfile reads all 20, whatever the end record says
    caps = Caps(entries=5, entries_name="TRACER_MAX_CLASS_ENTRIES")
    with pytest.raises(GradingError) as e:
        read_zip(lying, caps)
    assert str(e.value) == (
        "more than 5 entries in its central directory (its end record says 1); at most 5 (TRACER_MAX_CLASS_ENTRIES)"
    )
    assert len(read_zip(lying, Caps(entries=20))) == 20


def test_archive_a_lying_end_record_of_many_entries_is_refused_holding_little():
    """60 000 entries said to be 1 (the issue's were 10⁶, through the API: 22.8 s and 568 MB more): refused
    after reading 5001 headers, holding little (tracemalloc), where zipfile's ZipInfos would be tens of MB."""
    lying = lying_zip(many_entries(60_000))
    tracemalloc.start()
    try:
        with pytest.raises(GradingError, match=r"^more than 5000 entries in its central directory \(its end record"):
            read_zip(io.BytesIO(lying))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2_000_000, peak


@pytest.mark.parametrize(
    "entry, words",
    [
        ({"data": deflated(b"{}"), "size": 2, "crc": 12345}, "a.json: bad CRC-32 (the entry is corrupt)"),
        ({"data": b"\xff" * 40, "size": 10}, "a.json: cannot unpack it (error: Error -3 while decompressing data"),
        ({"data": deflated(b"{}")[:1], "size": 2, "crc": zlib.crc32(b"{}")}, "a.json: holds 0 bytes; its header"),
        ({"data": b"{}", "size": 2, "method": 12, "crc": zlib.crc32(b"{}")}, "a.json: compressed with method 12; only"),
        ({"data": b"{}", "size": 2, "flags": 0x801}, "a.json: is encrypted"),
    ],
    ids=["bad-crc", "garbage-deflate", "cut-short", "bzip2", "encrypted"],
)
def test_archive_broken_entries_are_named(entry, words):
    with pytest.raises(GradingError) as e:
        read_zip(raw_zip([{"name": "a.json", **entry}]))
    assert str(e.value).startswith(words), str(e.value)


def test_archive_not_a_zip_and_what_is_skipped(tmp_path):
    for garbage in (b"", b"hello", b"PK\x05\x06" + b"\0" * 10, class_zip()[:-30]):
        with pytest.raises(GradingError, match="^not a zip file"):
            read_zip(garbage)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name in ("hw4/a.json", "hw4/.b.json", "__MACOSX/hw4/._a.json", "hw4/notes.txt", "/abs.json",
                     "hw4/../up.json", "hw4/c/scene.json", "hw4/d.PNG"):  # fmt: skip
            z.writestr(name, "{}")
    files = unpack_zip(io.BytesIO(buf.getvalue()), tmp_path / "out")
    assert sorted(files) == ["hw4/a.json", "hw4/c/scene.json", "hw4/d.PNG"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["00000.json", "00001.json", "00002.png"]
    assert all(p.read_bytes() == b"{}" for p in files.values())


# -------------------------------------------------------------------------------- the upload route


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    """The app with one real render worker; small caps for the upload's limits: at most 40 entries and
    2 MB of files per class."""
    with api_client(tmp_path_factory.mktemp("upload-data"), workers=1, max_class_entries=40,
                    max_class_bytes=2_000_000) as client:  # fmt: skip
        yield client


def post(client, parts: dict | None = None, files: list | None = None, **kw):
    data = {"assignment": assignment_text()} if parts is None else parts
    return client.post("/api/grade/upload", data=data, files=files, **kw)


def finished(client, url: str) -> dict:
    return wait_for(lambda: (s := client.get(url).json())["status"] != "running" and s, 240, "the grading run", 0.2)


def test_upload_a_zip_grades_the_example_class(app):
    """The page's way: a multipart body with the assignment and the class as a zip, parsed as a stream;
    the same grades as every other way (tests/tracer/grading/test_grading.py)."""
    r = post(app, files={"class": ("hw4.zip", class_zip(), "application/zip")})
    assert r.status_code == 202, r.text
    run = r.json()
    assert r.headers["location"] == run["url"]
    assert run["students"] == sorted(EXPECTED)
    state = finished(app, run["url"])
    assert state["status"] == "done", state
    assert {x["student"]: (x["score"], x["status"]) for x in state["reports"]} == EXPECTED
    assert (state["graded"], state["renders_done"], state["renders_total"]) == (9, 7, 7)  # mean, 2 baselines, 4
    assert state["summary"]["statistics"]["mean_percent"] == pytest.approx(46.03, abs=0.01)
    csv = app.get(f"{run['url']}/summary.csv").text
    assert csv.splitlines()[1].startswith("alice,scene,graded,13.0,13.0")
    folder = app.app.state.settings.data_dir / "grades" / run["id"]
    kept = sorted(p.name for p in (folder / "submissions").iterdir())
    assert len(kept) == 9
    assert kept[0] == "00000.json"  # the students' files, as the run keeps them
    assert not list((folder.parent / ".uploads").iterdir())  # the upload's staging folder is gone
    # its renders wrote only what grading reads: the final image and the AOVs' floats, no previews or pictures
    store = app.app.state.store
    jobs = [j for j in store.list_jobs(limit=100)[0] if (j["name"] or "").startswith("grading: ")]
    assert len(jobs) >= 7
    for job in jobs:
        files = sorted(p.name for p in store.job_file(job["id"], JobFile.image_exr).parent.iterdir())
        assert files == sorted([JobFile.image_png, JobFile.image_exr, JobFile.aov_floats]), files
        assert job["preview"] == job["passes_done"]  # published once, at the end
        r = app.get(f"/api/jobs/{job['id']}/aov")
        assert r.status_code == 404 and "rendered for grading" in r.json()["errors"][0]["message"], r.text


def test_upload_the_json_route_grades_a_zip_unpacked_on_disk(app):
    """POST /api/grade with the example class as a base64 zip: unpacked to files as an upload is, the same
    grades; the submissions' names are those inside the zip's top folder, as before."""
    body = {"assignment": json.loads(assignment_text()), "zip": base64.b64encode(class_zip()).decode()}
    r = app.post("/api/grade", json=body)
    assert r.status_code == 202, r.text
    state = finished(app, r.json()["url"])
    assert {x["student"]: (x["score"], x["status"]) for x in state["reports"]} == EXPECTED
    folder = app.app.state.settings.data_dir / "grades" / r.json()["id"]
    assert len(list((folder / "submissions").iterdir())) == 9
    assert not list((folder.parent / ".uploads").iterdir())


def test_upload_files_parts_name_their_students(app):
    """One part per file, as the page sends picked files: students by file name (Unicode letters kept), a
    folder in the name as in a zip, other files skipped."""
    files = [
        ("files", ("Zoë O'Brien.json", (CLASS / "alice.json").read_bytes(), "application/json")),
        ("files", ("王小明.png", (CLASS / "grace.png").read_bytes(), "image/png")),
        ("files", ("frank/scene.json", (CLASS / "frank" / "scene.json").read_bytes(), "application/json")),
        ("files", ("notes.txt", b"not a submission", "text/plain")),
    ]
    r = post(app, files=files)
    assert r.status_code == 202, r.text
    state = finished(app, r.json()["url"])
    scores = {x["student"]: (x["score"], x["status"]) for x in state["reports"]}
    assert scores == {"Zoë_O_Brien": (13.0, "graded"), "王小明": (7.0, "graded"), "frank": (0.0, "invalid")}


def test_upload_a_zip_bomb_is_refused_with_the_entry_named(app, bomb):
    """1 MB on the wire, 1 GiB inside, 100 B declared: a 422 at `class` naming the entry."""
    r = post(app, files={"class": ("bomb.zip", bomb, "application/zip")})
    assert r.status_code == 422, r.text
    assert r.json()["errors"] == [{"path": "class", "message": "hw4/bomb.json: holds more than the 100 bytes its "
                                   "header declares"}]  # fmt: skip


@pytest.mark.parametrize(
    "make, status, path, words",
    [
        (lambda: {"class": ("x.zip", b"garbage")}, 422, "class", "not a zip file"),
        (lambda: {"class": ("x.zip", raw_zip([{"name": "hw4/a.json", "data": deflated(b"{}"), "size": 2, "crc": 1}]))},
         422, "class", "hw4/a.json: bad CRC-32"),
        (lambda: {"class": ("x.zip", raw_zip([{"name": f"s{i}.json", "data": b"{}", "method": 0, "size": 2,
                                              "crc": zlib.crc32(b"{}")} for i in range(41)]))},
         422, "class", "41 entries; at most 40 (TRACER_MAX_CLASS_ENTRIES)"),
        (lambda: {"class": ("x.zip", lying_zip(many_entries(2000)))},
         422, "class", "more than 40 entries in its central directory (its end record says 1); at most 40 "
                       "(TRACER_MAX_CLASS_ENTRIES)"),
        (lambda: {"class": ("x.zip", _many_bytes())},
         422, "class", "the class unpacks to more than 2000000 bytes (TRACER_MAX_CLASS_BYTES)"),
        (lambda: {"class": ("x.zip", raw_zip([{"name": "notes.txt", "data": b"x", "method": 0, "size": 1,
                                              "crc": zlib.crc32(b"x")}]))},
         422, "class", "no submissions in it (.json, .png or .exr files)"),
    ],
    ids=["garbage", "bad-crc", "too-many-entries", "lying-end-record", "too-many-bytes", "no-submissions"],
)  # fmt: skip
def test_upload_refuses_a_bad_zip_with_a_422(app, make, status, path, words):
    r = post(app, files=make())
    assert r.status_code == status, r.text
    [error] = r.json()["errors"]
    assert error["path"] == path and words in error["message"], error


def _many_bytes() -> bytes:
    """Three honest 900 KB scenes: past the 2 MB cap on the class together (not on one file)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("a.json", "b.json", "c.json"):
            z.writestr(name, " " * 900_000)
    return buf.getvalue()


def test_upload_refuses_bad_requests(app):
    zip_part = {"class": ("hw4.zip", class_zip())}
    r = post(app, parts={}, files=zip_part)
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "assignment"
    r = post(app, parts={"assignment": '{\n  "name": 1,,\n}'}, files=zip_part)
    assert r.status_code == 422
    assert r.json()["errors"][0]["message"].startswith("invalid JSON at line 2, column")
    a = json.loads(assignment_text())
    a["requirements"][0]["check"] = "glas"
    r = post(app, parts={"assignment": json.dumps(a)}, files=zip_part)
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "assignment.requirements[0].check"
    r = post(app, parts={"assignment": "[" * 100 + "]" * 100}, files=zip_part)
    assert r.status_code == 422
    assert "nested 100 levels deep" in r.json()["errors"][0]["message"]
    r = post(app, parts={}, files={"assignment": (None, assignment_text())})  # multipart, without a class
    assert r.status_code == 422
    assert "the class is missing" in r.json()["errors"][0]["message"]
    r = post(app, files=[*zip_part.items(), ("files", ("a.json", b"{}"))])
    assert r.status_code == 422
    assert "not both" in r.json()["errors"][0]["message"]
    r = post(app, files={"homework": ("a.json", b"{}")})
    assert r.status_code == 422
    assert r.json()["errors"][0]["message"].startswith("unknown part 'homework'")
    r = app.post("/api/grade/upload", json={"assignment": {}})
    assert r.status_code == 415
    assert "multipart/form-data" in r.json()["errors"][0]["message"]
    r = post(app, files=[("files", (f"s{i}.json", b"{}")) for i in range(41)])
    assert r.status_code == 422
    assert "more than 40 files" in r.json()["errors"][0]["message"]
    r = post(app, files=[("files", ("big.json", b" " * 2_100_000))])
    assert r.status_code == 422
    assert r.json()["errors"][0] == {"path": "files", "message": "big.json: the files are more than 2000000 bytes "
                                     "together (TRACER_MAX_CLASS_BYTES)"}  # fmt: skip


def test_upload_past_its_size_is_refused_by_content_length_and_by_bytes_streamed(app):
    """The request gate does not buffer an upload: it counts it, against TRACER_MAX_CLASS_BYTES plus
    TRACER_MAX_BODY_BYTES (2 MB + 2 MB here), by Content-Length and by the bytes that arrive."""
    limit = 2_000_000 + 2_000_000
    r = app.post("/api/grade/upload", content=b"x" * 10, headers={"content-type": "multipart/form-data; boundary=b",
                                                                  "content-length": str(limit + 1)})  # fmt: skip
    assert r.status_code == 413
    assert f"larger than {limit} bytes (TRACER_MAX_CLASS_BYTES" in r.text

    def chunks():  # no Content-Length: chunked, counted as it comes
        yield b'--b\r\nContent-Disposition: form-data; name="class"; filename="x.zip"\r\n\r\n'
        for _ in range(70):
            yield b"\0" * 65536

    r = app.post("/api/grade/upload", content=chunks(), headers={"content-type": "multipart/form-data; boundary=b"})
    assert r.status_code == 413
    assert f"larger than {limit} bytes" in r.text


def test_upload_the_json_route_reads_its_zip_with_the_same_bounds(app, bomb):
    """POST /api/grade with a base64 zip (small classes): the same bounded reader."""
    body = {"assignment": json.loads(assignment_text()), "zip": base64.b64encode(bomb).decode()}
    r = app.post("/api/grade", json=body)
    assert r.status_code in (413, 422), r.text  # 1.4 MB of base64: under 2 MB
    assert r.json()["errors"][0]["message"] == "hw4/bomb.json: holds more than the 100 bytes its header declares"


def corrupted_byte() -> bytes:
    """The example class's zip with one byte of alice.json's deflated data flipped."""
    data = bytearray(class_zip())
    data[data.index(b"hw4/alice.json") + len("hw4/alice.json") + 40] ^= 0xFF
    return bytes(data)


@pytest.mark.parametrize("route", ["json", "upload"])
@pytest.mark.parametrize(
    "make, words",
    [
        (corrupted_byte, "hw4/alice.json: "),
        (lambda: raw_zip([{"name": "hw4/a.json", "data": deflated(b"{}"), "size": 2, "crc": 1}]),
         "hw4/a.json: bad CRC-32 (the entry is corrupt)"),
        (lambda: raw_zip([{"name": "hw4/a.json", "data": b"\xff" * 40, "size": 10}]), "hw4/a.json: cannot unpack it"),
        (lambda: b"PK\x03\x04" + bytes(range(256)) * 8, "not a zip file"),
    ],
    ids=["corrupted-byte", "bad-crc", "garbage-stream", "garbage"],
)  # fmt: skip
def test_upload_both_routes_answer_a_broken_zip_with_a_422_naming_the_entry(app, route, make, words):
    """The issue's zips, through the JSON route (base64) and the upload: a 422 at the zip's field naming the
    entry, never a 500; nothing of them is left in the staging folder."""
    data = make()
    if route == "json":
        body = {"assignment": json.loads(assignment_text()), "zip": base64.b64encode(data).decode()}
        r, where = app.post("/api/grade", json=body), "zip"
    else:
        r, where = post(app, files={"class": ("hw4.zip", data, "application/zip")}), "class"
    assert r.status_code == 422, r.text
    [error] = r.json()["errors"]
    assert error["path"] == where and error["message"].startswith(words), error
    uploads = app.app.state.settings.data_dir / "grades" / ".uploads"
    assert not uploads.exists() or not list(uploads.iterdir())


def test_upload_the_json_route_unpacks_to_disk_never_holding_the_class(app):
    """The JSON route's zip (base64 in the body) used to be unpacked in memory: 70 entries of 19.9 MB of zeros
    (1.4 MB of zip) were held at 1.39 GB. Now it is unpacked to files like an upload, a chunk at a time:
    eight entries of 19.9 MB under a cap of 150 MB are refused at the eighth, by name, and Python's peak
    allocation (tracemalloc, the app runs in this process) stays far under one entry's size."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        for k in range(8):
            z.writestr(f"hw4/s{k}.json", bytes(19_900_000))
    body = {"assignment": json.loads(assignment_text()), "zip": base64.b64encode(buf.getvalue()).decode()}
    del buf
    settings = app.app.state.settings
    saved = settings.max_class_bytes
    settings.max_class_bytes = 150_000_000
    tracemalloc.start()
    try:
        r = app.post("/api/grade", json=body)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
        settings.max_class_bytes = saved
    assert r.status_code == 422, r.text
    assert r.json()["errors"] == [{"path": "zip", "message": "hw4/s7.json: the class unpacks to more than 150000000 "
                                   "bytes (TRACER_MAX_CLASS_BYTES)"}]  # fmt: skip
    assert peak < 16_000_000, peak  # before: every entry unpacked in memory, 140 MB
    assert not list((settings.data_dir / "grades" / ".uploads").iterdir())  # the unpacked files are gone


def test_upload_openapi_documents_the_multipart_body(app):
    op = app.get("/openapi.json").json()["paths"]["/api/grade/upload"]["post"]
    schema = op["requestBody"]["content"]["multipart/form-data"]["schema"]
    assert {"assignment", "class", "files"} <= set(schema["properties"])
    assert schema["required"] == ["assignment"]


def test_upload_path_in_a_zip_stays_inside(tmp_path):
    """Names never become paths: a zip's entries are written under our own numbers."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("../../etc/evil.json", "{}")
        z.writestr("ok/../../evil2.json", "{}")
        z.writestr("fine.json", "{}")
    files = unpack_zip(io.BytesIO(buf.getvalue()), tmp_path / "out")
    assert list(files) == ["fine.json"]
    assert files["fine.json"].parent == tmp_path / "out"
    assert not (tmp_path / "evil.json").exists() and not Path("/etc/evil.json").exists()


def test_upload_the_repositorys_assignment_with_its_reference_file_beside_it(app):
    """`-F assignment=@scenes/grading/assignment.json` names its reference scene as a file: sent as a
    `reference` part beside it (`-F reference=@scenes/grading/reference.json`), the class is graded as
    with the scene inline; without it, the 422 says to send it so."""
    root = ROOT / "scenes" / "grading"
    parts = {"assignment": ("assignment.json", (root / "assignment.json").read_bytes(), "application/json"),
             "reference": ("reference.json", (root / "reference.json").read_bytes(), "application/json"),
             "files": ("grace.png", (root / "class" / "grace.png").read_bytes(), "image/png")}  # fmt: skip
    r = app.post("/api/grade/upload", files=parts)
    assert r.status_code == 202, r.text
    state = finished(app, r.json()["url"])
    assert {x["student"]: (x["score"], x["status"]) for x in state["reports"]} == {"grace": EXPECTED["grace"]}
    # an image can earn its readability's and the image tests' points, 7 of the scene's 13
    assert state["max_scores"] == {"scene": 13.0, "image": 7.0}
    assert state["max_score"] == 13.0
    assert state["summary"]["statistics"]["max_scores"] == {"image": 7.0}
    del parts["reference"]
    r = app.post("/api/grade/upload", files=parts)
    assert r.status_code == 422 and r.json()["errors"][0]["path"] == "assignment.reference.scene", r.text
    r = app.post("/api/grade/upload", files={**parts, "reference": ("r.json", b"[1]", "application/json")})
    assert r.status_code == 422
    assert (r.json()["errors"] == [
        {"path": "reference", "message": "the reference scene must be a JSON object {...}"}])  # fmt: skip
