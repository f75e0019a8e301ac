"""The reference documents of docs/ (the scene format, the service, the page, grading) as HTML pages,
rendered on the server so the page's "Format reference" link works without internet.

GET /reference/ lists them; GET /reference/NAME.md is one, its headings with the anchors GitHub gives
them (so links such as scene-format.md#camera-rays work both there and here). The documents are
the repository's own trusted files: their HTML comments (the field-table markers) pass through. A
document's links to the server's own pages name the address the request came to (`here`), not the default
port the repository's text must write.
"""

from __future__ import annotations

import html
import re
from functools import lru_cache
from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse
from markdown_it import MarkdownIt
from markdown_it.renderer import RendererHTML

from server.api.errors import ApiError
from server.core.paths import DOCS
from tracer.tools.scene_docs import slug

router = APIRouter(prefix="/reference", tags=["reference"], include_in_schema=False)

PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title} · Ray tracing for teaching</title>
<link rel="icon" href="data:,">
<link rel="stylesheet" href="/css/reference.css">
</head>
<body>
<header class="top"><a href="/">Ray tracing for teaching</a> <span>·</span> <a href="/reference/">Reference</a>
<span class="links"><a href="/reference/scene-format.md">Scene format</a> · <a href="/docs">API</a></span></header>
<main class="doc">
{body}
</main>
</body>
</html>
"""


def _markdown() -> MarkdownIt:
    md = MarkdownIt("commonmark", {"html": True, "typographer": False}).enable("table")

    def heading_ids(state) -> None:
        seen: dict[str, int] = {}
        for i, token in enumerate(state.tokens):
            if token.type == "heading_open":
                base = slug(state.tokens[i + 1].content)
                n = seen.get(base, 0)
                seen[base] = n + 1
                token.attrSet("id", base if n == 0 else f"{base}-{n}")

    md.core.ruler.push("heading_ids", heading_ids)
    renderer = md.renderer
    assert isinstance(renderer, RendererHTML)  # (MarkdownIt's default renderer)
    default_fence = renderer.rules["fence"]
    default_block = renderer.rules["code_block"]

    def focusable(default):
        """A code block may scroll sideways: it takes the keyboard's focus (so the arrow keys scroll it, WCAG
        2.1.1) and is named as a group ("code, json"), which a screen reader announces on entering it."""

        def render(_renderer, tokens, idx, options, env) -> str:  # a method of the renderer (add_render_rule)
            lang = tokens[idx].info.strip().split(" ")[0] if tokens[idx].type == "fence" else ""
            label = html.escape(f"code, {lang}" if lang else "code", quote=True)
            out = default(tokens, idx, options, env)
            return out.replace("<pre>", f'<pre tabindex="0" role="group" aria-label="{label}">', 1)

        return render

    md.add_render_rule("fence", focusable(default_fence))
    md.add_render_rule("code_block", focusable(default_block))
    return md


MD = _markdown()


def _title(text: str, name: str) -> str:
    found = re.search(r"^# (.+)$", text, re.M)
    return found[1].strip() if found else name


@lru_cache(maxsize=32)
def _render(path: Path, mtime: float) -> tuple[str, str]:
    text = path.read_text(encoding="utf-8")
    return _title(text, path.stem), MD.render(text)


def _doc(name: str) -> Path:
    path = DOCS / f"{name}.md"
    if not re.fullmatch(r"[A-Za-z0-9_-]+", name) or not path.is_file():
        raise ApiError(404, [{"path": "name", "message": f"no document named '{name[:64]}.md'"}])
    return path


@router.get("/", response_class=HTMLResponse)
def index() -> HTMLResponse:
    items = []
    for path in sorted(DOCS.glob("*.md")):
        title = _title(path.read_text(encoding="utf-8"), path.stem)
        items.append(f'<li><a href="{path.name}">{html.escape(title)}</a> <code>docs/{path.name}</code></li>')
    body = "<h1>Reference</h1>\n<ul>\n" + "\n".join(items) + "\n</ul>"
    return HTMLResponse(PAGE.format(title="Reference", body=body))


DEFAULT_BASE = re.compile(r"http://127\.0\.0\.1:8000(?=/)")  # a page of the server at its default address


def here(body: str, request: Request) -> str:
    """A document's links to pages of the server at its default address (`http://127.0.0.1:8000/reference/...`,
    as the repository's files must write them) with the address this request reached it at instead."""
    base = html.escape(str(request.base_url).rstrip("/"))
    return DEFAULT_BASE.sub(lambda _: base, body)


@router.get("/{name}.md", response_class=HTMLResponse)
def document(name: str, request: Request) -> HTMLResponse:
    path = _doc(name)
    title, body = _render(path, path.stat().st_mtime)
    return HTMLResponse(PAGE.format(title=html.escape(title), body=here(body, request)))
