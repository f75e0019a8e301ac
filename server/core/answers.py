"""Answers that are not JSON, as plain data: an HTML page, a redirect. The LTI tool and the course's LMS side
(a launch's page, the picker, a refusal) say what to answer with these; server/api/answers.py makes the HTTP
response, so nothing below server/api builds one."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Page:
    """An HTML page: its text, its status (a refusal's page says why with its status too), its headers (a page
    of its own policy sets Content-Security-Policy; pages are never cached)."""

    html: str
    status: int = 200
    headers: dict[str, str] = field(default_factory=lambda: {"Cache-Control": "no-store"})


@dataclass
class Redirect:
    """Go on to `url` (303: the browser GETs it, whatever the launch was posted with)."""

    url: str
    status: int = 303


Answer = Page | Redirect
