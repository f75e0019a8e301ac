"""Split compound asserts (issue #40, item 6): `assert a and b and c` becomes `assert a`, `assert b`, `assert c`, so
that a failure says which part failed (pytest shows that part's values) instead of the whole conjunction.

    python tests/support/split_asserts.py [--check] [FILES or FOLDERS ...]   (default: tests/)

then `ruff format` the files it changed. `--check` changes nothing and exits 1 when an assert would be split.

An assert is split only where that says the same thing in the same order: its test is an `and` at the top (not
under `not`, nor inside an `or`), it has no message (a message speaks of the whole), each operand is free of
side effects as `ast` sees it (names, attributes, subscripts, constants, comparisons, arithmetic, displays,
comprehensions, and calls of builtins and methods that only read: `len`, `isinstance`, `.get`, `.startswith`,
`.json()`, ...; never a walrus, an await or a yield), and it is whole on its lines: the first thing on its first
line, nothing after it on its last but a comment, no comment inside it (a comment goes to the last assert). The
operands keep their text (and their parentheses where they span lines); the split asserts keep the indentation.
Python evaluates the parts of an `and` left to right and stops at the first falsy one, as the split asserts do.
"""

from __future__ import annotations

import ast
import io
import sys
import tokenize
from pathlib import Path

PURE_FUNCTIONS = frozenset(
    "len isinstance issubclass set frozenset sorted list tuple dict str int float bool abs min max any all round "
    "type hasattr repr bytes range enumerate zip reversed sum getattr callable".split()
)
PURE_METHODS = frozenset(
    "get keys values items count index startswith endswith strip lstrip rstrip lower upper split rsplit splitlines "
    "partition rpartition find rfind isdigit isalpha isalnum isspace issubset issuperset isdisjoint exists is_file "
    "is_dir is_absolute read_text read_bytes json is_set is_alive poll done cancelled result relative_to with_suffix "
    "as_posix decode encode hex casefold format replace join copy getvalue qsize empty full inner_text "
    "text_content get_attribute is_visible is_hidden is_checked is_enabled is_disabled input_value".split()
)


def pure(node: ast.AST) -> bool:
    """Is evaluating `node` free of side effects, as far as its syntax tells?"""
    for n in ast.walk(node):
        if isinstance(n, (ast.NamedExpr, ast.Await, ast.Yield, ast.YieldFrom)):
            return False
        if isinstance(n, ast.Call):
            f = n.func
            if isinstance(f, ast.Name) and f.id in PURE_FUNCTIONS:
                continue
            if isinstance(f, ast.Attribute) and f.attr in PURE_METHODS:
                continue
            return False
    return True


def _comments(text: str) -> dict[int, int]:
    """Line number -> the column of the comment on that line."""
    out = {}
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            out[tok.start[0]] = tok.start[1]
    return out


def _cut(line: str, start: int | None = None, end: int | None = None) -> str:
    """A slice of a line by `ast`'s columns, which count UTF-8 bytes."""
    return line.encode()[start:end].decode()


def _segment(lines: list[str], node: ast.expr) -> str:
    """The source text of `node` (its own, without the parentheses around it)."""
    assert node.end_lineno is not None and node.end_col_offset is not None
    first, last = node.lineno - 1, node.end_lineno - 1
    if first == last:
        return _cut(lines[first], node.col_offset, node.end_col_offset)
    parts = [
        _cut(lines[first], node.col_offset),
        *lines[first + 1 : last],
        _cut(lines[last], None, node.end_col_offset),
    ]
    return "\n".join(p.rstrip("\n") for p in parts)


def splittable(node: ast.Assert) -> bool:
    test = node.test
    return node.msg is None and isinstance(test, ast.BoolOp) and isinstance(test.op, ast.And) and pure(test)


def split_text(text: str) -> tuple[str, int]:
    """The text with its compound asserts split, and how many asserts were split."""
    tree = ast.parse(text)
    lines = text.splitlines(keepends=True)
    comments = _comments(text)
    edits = []  # (first line index, last line index, replacement lines)
    for node in ast.walk(tree):
        if not isinstance(node, ast.Assert) or not splittable(node):
            continue
        assert node.end_lineno is not None and node.end_col_offset is not None
        first, last = node.lineno - 1, node.end_lineno - 1
        indent = _cut(lines[first], None, node.col_offset)
        if indent.strip():  # not the first thing on its line (`if x: assert ...`, `a; assert ...`)
            continue
        if any(line in comments for line in range(node.lineno, node.end_lineno)):
            continue  # a comment inside it: whose part would it be?
        rest = _cut(lines[last], node.end_col_offset).rstrip("\n")
        comment = ""
        if rest.strip():
            if node.end_lineno in comments and rest.strip().startswith("#"):
                comment = "  " + rest.strip()
            else:
                continue  # `assert a and b; x = 1`
        parts = []
        assert isinstance(node.test, ast.BoolOp)
        for operand in node.test.values:
            source = _segment(lines, operand)
            if "\n" in source:
                source = f"({source})"  # spans lines: held together by parentheses
            parts.append(f"{indent}assert {source}\n")
        parts[-1] = parts[-1].rstrip("\n") + comment + "\n"
        edits.append((first, last, parts))
    if not edits:
        return text, 0
    edits.sort(reverse=True)
    out = lines[:]
    for first, last, parts in edits:  # from the bottom up: the line numbers above stay right
        out[first : last + 1] = parts
    new = "".join(out)
    ast.parse(new)  # still Python
    return new, len(edits)


def files(args: list[str]) -> list[Path]:
    roots = [Path(a) for a in args] or [Path(__file__).resolve().parents[1]]
    out = []
    for root in roots:
        out += sorted(root.rglob("*.py")) if root.is_dir() else [root]
    return [p for p in out if "__pycache__" not in p.parts and p.resolve() != Path(__file__).resolve()]


def main(argv: list[str]) -> int:
    check = "--check" in argv
    changed = total = 0
    for path in files([a for a in argv if a != "--check"]):
        text = path.read_text()
        new, n = split_text(text)
        if n:
            changed += 1
            total += n
            if not check:
                path.write_text(new)
    print(f"{total} compound asserts {'to split' if check else 'split'} in {changed} files")
    return 1 if check and total else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
