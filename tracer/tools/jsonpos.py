"""Where a JSON path is in a JSON text, as line and column: the command line's errors say `file:line:col`,
as the page's editor marks them (web/js/jsonpos.js, whose rules this follows).

`positions(text)` maps each value's JSON path, written as the errors write it (`objects[2].radius`,
`materials["my glass"].kd`: tracer.errors.json_path), to the offset where an error at it is shown: a
member's key, an array item's or the root's value. `locate(text, path)` is the (line, column) of a path,
or of its nearest ancestor in the text (a missing field is shown where its object is).
"""

from __future__ import annotations

import json
import re
from json.decoder import scanstring  # pyright: ignore[reportAttributeAccessIssue]  (there, not in typeshed's stub)

from tracer.errors import json_path

_WS = re.compile(r"[ \t\n\r]*")
_DECODER = json.JSONDecoder()  # numbers, true, false, null, and the NaN and Infinity the scene parser accepts
_PATH_PART = re.compile(r'\.?([A-Za-z_][A-Za-z0-9_-]*)|\[(\d+)\]|\[("(?:[^"\\]|\\.)*")\]')


def parse_path(path: str) -> list[str | int]:
    """'objects[2].radius' -> ['objects', 2, 'radius'] (the inverse of json_path)."""
    parts: list[str | int] = []
    for m in _PATH_PART.finditer(path):
        parts.append(m[1] if m[1] is not None else int(m[2]) if m[2] is not None else json.loads(m[3]))
    return parts


def positions(text: str) -> dict[str, int]:
    """JSON path -> the offset where an error at it is shown; {} for a text that is not JSON."""
    out: dict[str, int] = {}

    def skip(i: int) -> int:
        m = _WS.match(text, i)
        assert m is not None, "whitespace* matches the empty string too"
        return m.end()

    def value(i: int, parts: list, shown_at: int | None) -> int:
        i = skip(i)
        out[json_path(parts)] = i if shown_at is None else shown_at
        opening = text[i : i + 1]
        if opening not in ("{", "["):
            return _DECODER.raw_decode(text, i)[1]
        closing, i, n = "}" if opening == "{" else "]", skip(i + 1), 0
        while text[i : i + 1] != closing:
            if opening == "{":
                key_at = i
                key, i = scanstring(text, i + 1)
                i = value(skip(i) + 1, [*parts, key], key_at)  # past the ':'
            else:
                i = value(i, [*parts, n], None)
            n, i = n + 1, skip(i)
            if text[i : i + 1] == ",":
                i = skip(i + 1)
        return i + 1

    try:
        value(0, [], None)
    except (ValueError, IndexError, RecursionError):
        return {}
    return out


def line_col(text: str, offset: int) -> tuple[int, int]:
    """An offset as a 1-based (line, column)."""
    line_start = text.rfind("\n", 0, offset) + 1
    return text.count("\n", 0, offset) + 1, offset - line_start + 1


def locate(text: str, path: str, found: dict[str, int] | None = None) -> tuple[int, int] | None:
    """The (line, column) of `path` in the JSON `text`, or of its nearest ancestor there; None when the text
    is not JSON (`found`: the text's `positions`, when several paths are looked up)."""
    found = positions(text) if found is None else found
    parts = parse_path(path)
    for k in range(len(parts), -1, -1):
        at = found.get(json_path(parts[:k]))
        if at is not None:
            return line_col(text, at)
    return None
