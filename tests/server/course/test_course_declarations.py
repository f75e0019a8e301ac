"""The course mixins' cross-calls declared on CourseBase for the type checker (its `if TYPE_CHECKING:` block) say
what the real methods of `Course` are: the same parameters (names, kinds, defaults) and annotations, so that a
method changed in its module cannot leave pyright checking callers against an old declaration."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

from server.course import base
from server.course.service import Course


def declared() -> dict[str, ast.FunctionDef]:
    tree = ast.parse(Path(base.__file__).read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "CourseBase")
    block = next(
        n for n in cls.body if isinstance(n, ast.If) and isinstance(n.test, ast.Name) and n.test.id == "TYPE_CHECKING"
    )
    return {f.name: f for f in block.body if isinstance(f, ast.FunctionDef)}


def shape(sig: inspect.Signature) -> list[tuple[str, str, str, str]]:
    return [
        (p.name, p.kind.name, "" if p.default is p.empty else repr(p.default), str(p.annotation).replace(" ", ""))
        for p in sig.parameters.values()
    ]


def test_course_base_declares_each_cross_call_as_the_real_method_is():
    decls = declared()
    assert len(decls) >= 20, sorted(decls)  # the block was found and read
    for name, fn in decls.items():
        real = getattr(Course, name, None)
        assert real is not None, f"CourseBase declares {name}, which no mixin of Course defines"
        assert getattr(base.CourseBase, name, None) is None, f"{name}: declared only for the checker"
        namespace: dict = {}
        source = ast.unparse(ast.Module(body=[fn], type_ignores=[]))
        exec("from __future__ import annotations\n" + source, namespace)  # noqa: S102 (our own module's text)
        want = inspect.signature(real)
        got = inspect.signature(namespace[name])
        assert shape(got) == shape(want), f"{name}: declared {got}, defined {want}"
        assert str(got.return_annotation).replace(" ", "") == str(want.return_annotation).replace(" ", ""), name
