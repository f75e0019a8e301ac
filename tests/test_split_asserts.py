"""tests/support/split_asserts.py splits `assert a and b` into one assert per part where that says the same thing:
no message, no side effect in the parts, the assert whole on its lines (issue #40, item 6)."""

from __future__ import annotations

import ast

from tests.support.split_asserts import files, split_text


def test_split_asserts_splits_a_conjunction_into_its_parts():
    text = 'def t(r, x):\n    assert r.status_code == 200 and "é" in r.text and len(x) > 2  # the page\n'
    new, n = split_text(text)
    assert n == 1
    assert new == (
        'def t(r, x):\n    assert r.status_code == 200\n    assert "é" in r.text\n    assert len(x) > 2  # the page\n'
    )


def test_split_asserts_holds_a_part_over_several_lines_in_parentheses():
    text = "assert a and (\n    b == [1,\n          2]\n) and c\n"
    new, n = split_text(text)
    assert n == 1
    assert [ast.unparse(s) for s in ast.parse(new).body] == ["assert a", "assert b == [1, 2]", "assert c"]


def test_split_asserts_leaves_what_a_split_would_change_or_cannot_place():
    for text in (
        'assert a and b, "a message speaks of the whole"\n',
        "assert a or b and c\n",
        "assert not (a and b)\n",
        "assert queue.pop() and b\n",  # a call that may change something
        "assert (m := f()) and m.x\n",
        "if x: assert a and b\n",
        "assert a and b; y = 1\n",
        "assert (a  # one comment inside\n        and b)\n",
    ):
        assert split_text(text) == (text, 0), text


def test_split_asserts_keeps_calls_that_only_read():
    new, n = split_text('assert isinstance(d, dict) and d.get("k") and p.read_text().startswith("x")\n')
    assert n == 1
    assert new.count("assert ") == 3


def test_split_asserts_finds_no_compound_assert_left_in_the_tests():
    """The suite keeps its asserts one part each (issue #40, item 6): a new `assert a and b` is split by
    `python tests/support/split_asserts.py FILE`, or written as two asserts."""
    left = {str(p): n for p in files([]) if (n := split_text(p.read_text())[1])}
    assert left == {}
