"""How deeply JSON text nests (`json_depth`), read without parsing it: the request gate's check of a body
(server/api/gate.py) and of a JSON part of an upload (server/grading/handin.py) before any parser sees it."""

from __future__ import annotations

import re

import numpy as np

_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"')
_NOT_BRACKETS = bytes(c for c in range(256) if c not in b"[]{}")


def json_depth(body: bytes) -> int:
    """The deepest nesting of arrays and objects in JSON text (brackets inside strings ignored): in array
    operations that let other threads run (`_depth_of_arrays`), or, for text those do not read as JSON
    reads it (a string left open, a backslash outside strings), by stripping strings with a regular
    expression, as `_depth_by_regex` did first."""
    depth = _depth_of_arrays(body)
    return _depth_by_regex(body) if depth is None else depth


def _depth_by_regex(body: bytes) -> int:
    brackets = _STRING.sub(b"", body).translate(None, _NOT_BRACKETS)
    if not brackets:
        return 0
    b = np.frombuffer(brackets, dtype=np.uint8)
    steps = np.where((b == ord("[")) | (b == ord("{")), 1, -1)
    return int(np.cumsum(steps).max())


def _depth_of_arrays(body: bytes) -> int | None:
    """`json_depth` with numpy alone (which releases the interpreter lock, so the event loop goes on while a
    thread reads a large body), or None where that could differ from `_depth_by_regex`: every string must
    close and no backslash may stand outside one, as in JSON. Arrays of one byte per byte of the body,
    and of one number per backslash or bracket."""
    b = np.frombuffer(body, dtype=np.uint8)
    if not b.size:
        return 0
    backslash, quote = b == ord("\\"), b == ord('"')
    slashes = np.flatnonzero(backslash)
    if slashes.size:  # the byte after an odd run of backslashes is escaped
        breaks = np.flatnonzero(np.diff(slashes) != 1)
        first, last = slashes[np.r_[0, breaks + 1]], slashes[np.r_[breaks, slashes.size - 1]]
        after = last[((last - first) % 2 == 0) & (last + 1 < b.size)] + 1
        quote[after] = False
    inside = np.bitwise_xor.accumulate(quote.view(np.uint8)).view(bool)  # from an opening quote to its closing one
    if inside[-1]:
        return None  # a string left open
    if slashes.size and not inside[slashes].all():
        return None  # a backslash outside strings
    at = np.flatnonzero(((b == ord("[")) | (b == ord("{")) | (b == ord("]")) | (b == ord("}"))) & ~inside)
    if not at.size:
        return 0
    opening = (b[at] == ord("[")) | (b[at] == ord("{"))
    return int(np.cumsum(np.where(opening, 1, -1), dtype=np.int64).max())
