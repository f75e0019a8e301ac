"""The LTI pages' HTML: a refused launch (which check failed, in plain words) and the default handler's page.

Small and self-contained, with the site's stylesheet; every value is escaped. A refused launch's page names its
check twice: for a person (`<strong>nonce</strong>: this launch was used already`) and for tests and support
(`data-check="nonce"`).
"""

from __future__ import annotations

from html import escape

from starlette.responses import HTMLResponse

TEMPLATE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<link rel="icon" href="data:,">
<link rel="stylesheet" href="/css/app.css">
</head>
<body>
<main id="main"{attrs}>
{body}
</main>
</body>
</html>
"""


def page(title: str, body_html: str, status: int = 200, attrs: str = "") -> HTMLResponse:
    """A small page: `title` (text, escaped here) and `body_html` (HTML, escaped by the caller)."""
    html = TEMPLATE.format(title=escape(title), attrs=attrs, body=body_html)
    return HTMLResponse(html, status_code=status, headers={"Cache-Control": "no-store"})


def error_page(check: str, message: str, status: int = 400) -> HTMLResponse:
    """The page of a refused launch or login: `check` the failed check's name, `message` what went wrong."""
    body = (
        "<h1>The launch was refused</h1>\n"
        f'<p class="message" data-kind="error"><strong>{escape(check)}</strong>: {escape(message, quote=False)}</p>\n'
        "<p>Open the link again from your course. If this page comes back, tell your instructor or the "
        "administrator of this server what it says.</p>"
    )
    return page("Launch refused", body, status, f' class="lti-refused" data-check="{escape(check, quote=True)}"')


def deep_link_form(return_url: str, jwt: str, summary: str = "") -> HTMLResponse:
    """The page that carries a deep-linking answer (services.deep_link_response's JWT) back to the platform: a
    form posted to the settings' deep_link_return_url by the person's own click (no script: the site's policy
    allows none inline; its form-action allows the platforms' origins, server/core/security.py)."""
    body = (
        "<h1>Add to the course</h1>\n"
        f"<p>{escape(summary, quote=False)}</p>\n"
        f'<form method="post" action="{escape(return_url, quote=True)}">\n'
        f'<input type="hidden" name="JWT" value="{escape(jwt, quote=True)}">\n'
        '<button type="submit">Add</button>\n</form>'
    )
    return page("Add to the course", body)
