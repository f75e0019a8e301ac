"""An upload of the example class to grade: the assignment's text and the class as a zip
(tests/server/grading/test_grading_upload.py and the tests that upload it too)."""

from __future__ import annotations

import io
import json
import zipfile

from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"


CLASS = EXAMPLE / "class"


def assignment_text() -> str:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return json.dumps(a)


def class_zip(top: str = "hw4/") -> bytes:
    """The example class as a zip (deflated), in one top folder."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(CLASS.rglob("*")):
            if f.is_file():
                z.write(f, top + f.relative_to(CLASS).as_posix())
    return buf.getvalue()
