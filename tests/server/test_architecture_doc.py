"""docs/architecture.md names every module of server/ and tracer/, and every page and module of web/ (its .html and
.js files): a module added, moved or renamed without its line in the map fails here. Read generically from the doc's
shapes, so that packages may move:

- a code block drawn as a tree (`server/`, then `core/` indented under it, then `settings.py` under that): each
  name resolves against the folders above it, and a folder's line names the modules its words list;
- a table row whose first cell is a folder (`` `grading/` ``) names the modules its row lists, in that folder;
- anywhere under a `## tracer/`, `## server/` or `## web/` heading, a path (`jobs/lifecycle.py`,
  `server/api/deps.py`) names that module, from the repository's root or from the heading's package.

A package's `__init__.py` is named by its folder."""

from __future__ import annotations

import re

from tests.support.scene import ROOT

DOC = ROOT / "docs" / "architecture.md"
MODULES = {"server": ("*.py",), "tracer": ("*.py",), "web": ("*.js", "*.html")}  # each folder's modules
PACKAGES = tuple(MODULES)
# a module or a folder, with the folders before it: run.py, queue/base.py, jobs/, js/course/student.js
TOKEN = re.compile(r"(?<![\w./-])((?:[A-Za-z_]\w*/)*(?:[A-Za-z_]\w*\.(?:py|js|html)\b|[A-Za-z_]\w*/))")


def package_modules(packages: tuple[str, ...] = ("server", "tracer")) -> set[str]:
    return {
        p.relative_to(ROOT).as_posix()
        for pkg in packages
        for pattern in MODULES[pkg]
        for p in (ROOT / pkg).rglob(pattern)
    }


def _resolve(token: str, bases: list[str]) -> set[str]:
    if token.split("/")[0] in PACKAGES:
        return {token}
    return {base + token for base in bases}


def named(doc: str) -> set[str]:
    """The paths (modules `x/y.py`, folders `x/`) that the doc names, by the rules above."""
    out: set[str] = set()
    section = ""  # "server/" or "tracer/" under their headings
    code, stack = False, []  # in a code block: (indent, folder) of the tree's open folders
    for line in doc.splitlines():
        if line.startswith("#"):
            m = re.match(r"#+ (\w+)/", line)
            section = f"{m[1]}/" if m and f"{m[1]}" in PACKAGES else ("" if line.startswith("## ") else section)
            if section:
                out.add(section)
            continue
        if line.startswith("```"):
            code, stack = not code, []
            continue
        tokens = TOKEN.findall(line)
        if code:
            indent = len(line) - len(line.lstrip())
            while stack and stack[-1][0] >= indent:
                stack.pop()
            head = re.split(r"\s{2,}", line.strip())[0]
            folder = head if re.fullmatch(r"[\w/]+/", head) else None
            if folder is not None:
                tokens = tokens[1:]  # the folder itself
                base = folder if folder.split("/")[0] in PACKAGES else (stack[-1][1] if stack else section) + folder
                stack.append((indent, base))
                out.add(base)
            bases = [stack[-1][1]] if stack else [section]
        elif line.startswith("|"):
            first = line.split("|")[1].strip().strip("`")
            bases = [section + first] if first.endswith("/") else [section]
            if first.endswith("/"):
                out.add(section + first)
        else:
            bases = [section] if section else []
        for token in tokens:
            out |= _resolve(token, bases)
    return out


def unnamed(modules: set[str], names: set[str]) -> list[str]:
    def ok(path: str) -> bool:
        folder, _, name = path.rpartition("/")
        return (folder + "/") in names if name == "__init__.py" else path in names

    return sorted(m for m in modules if not ok(m))


def test_architecture_doc_names_every_module():
    assert unnamed(package_modules(), named(DOC.read_text())) == []


def test_architecture_doc_names_every_web_module():
    """web/'s pages and modules (the course's pages, the Build panel, LTI's pages, ...): one line each."""
    modules = package_modules(("web",))
    assert "web/index.html" in modules
    assert "web/js/course/student.js" in modules
    assert unnamed(modules, named(DOC.read_text())) == []


def test_architecture_doc_reading_resolves_trees_tables_and_paths():
    doc = """
## server/: the service
```
server/
  main.py, worker.py     the app
  jobs/                  what a job is
    store.py             the table
  queue/                 two backends: base.py
    embedded/            queue.py, pool.py,
                         wakeup.py
```
A route asks `jobs/service.py`; see server/core/ids.py.

## tracer/: the library
| `grading/` | the spec (`spec.py`) |
| `film.py` | PNG |
"""
    names = named(doc)
    for path in ("server/main.py", "server/worker.py", "server/jobs/store.py", "server/queue/base.py",
                 "server/queue/embedded/queue.py", "server/queue/embedded/wakeup.py", "server/jobs/service.py",
                 "server/core/ids.py", "tracer/grading/spec.py", "tracer/film.py",
                 "server/queue/embedded/"):  # fmt: skip
        assert path in names, path
    assert "server/store.py" not in names
    assert "server/queue/store.py" not in names  # a name stays in its folder
    assert "tracer/store.py" not in names
    assert "tracer/spec.py" not in names
    modules = {"server/jobs/store.py", "server/lti/store.py", "server/jobs/__init__.py", "server/lti/__init__.py"}
    assert unnamed(modules, names) == ["server/lti/__init__.py", "server/lti/store.py"]
    web = named(
        "## web/: the page\n```\nweb/\n  index.html   the page\n  js/\n    main.js    tabs\n    course/\n"
        "      student.js   a student's\n      mycourse.js, session.js\n```\nSee `web/js/build.js`.\n"
    )
    for path in ("web/index.html", "web/js/main.js", "web/js/course/student.js", "web/js/course/session.js",
                 "web/js/build.js"):  # fmt: skip
        assert path in web, path
    assert "web/js/student.js" not in web
    assert "web/main.js" not in web
