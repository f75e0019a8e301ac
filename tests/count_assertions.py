"""Counts what the suite asserts (issue #40): `assert` statements and Playwright `expect(...)` calls in tests/**/*.py,
and `assert.*(...)` / `assert(...)` calls in the JavaScript tests (tests/js/*.test.mjs, run by `node --test`).
`python tests/count_assertions.py [ROOT]` prints the totals, per folder of tests/; the before and after of a change
to the suite are in BENCHMARKS.md."""

from __future__ import annotations

import ast
import re
import sys
from collections import Counter
from pathlib import Path

JS_ASSERT = re.compile(r"\bassert(?:\.\w+)?\s*\(")


def count(root: Path) -> Counter:
    tests = root / "tests"
    found: Counter = Counter()
    for path in sorted(tests.rglob("*.py")):
        if "__pycache__" in path.parts or path.name == "count_assertions.py":
            continue
        folder = str(path.parent.relative_to(root))
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Assert):
                found[(folder, "assert")] += 1
            elif isinstance(node, ast.Call):
                f = node.func
                if (isinstance(f, ast.Name) and f.id == "expect") or (
                    isinstance(f, ast.Attribute) and f.attr == "expect"
                ):
                    found[(folder, "expect(")] += 1
    for path in sorted(tests.rglob("*.test.mjs")):
        folder = str(path.parent.relative_to(root))
        text = re.sub(r"^\s*//.*$", "", path.read_text(), flags=re.M)
        text = re.sub(r"^import .*$", "", text, flags=re.M)
        found[(folder, "js assert")] += len(JS_ASSERT.findall(text))
    return found


def main() -> None:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    found = count(root)
    for (folder, kind), n in sorted(found.items()):
        print(f"{folder:40} {kind:10} {n:6}")
    kinds = Counter()
    for (_, kind), n in found.items():
        kinds[kind] += n
    print("total", dict(sorted(kinds.items())), "all", sum(kinds.values()))


if __name__ == "__main__":
    main()
