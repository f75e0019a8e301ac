"""The services' plain answers (server/core/answers.py: a page, a redirect) as HTTP responses."""

from __future__ import annotations

from fastapi.responses import HTMLResponse, RedirectResponse, Response

from server.core.answers import Answer, Page


def respond(answer: Answer, headers: dict[str, str] | None = None) -> Response:
    if isinstance(answer, Page):
        return HTMLResponse(answer.html, status_code=answer.status, headers=answer.headers | (headers or {}))
    return RedirectResponse(answer.url, status_code=answer.status, headers=headers)
