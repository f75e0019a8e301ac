"""The LTI pages' HTML: a refused launch (which check failed, in plain words) and the default handler's page, as
plain `Page`s (server/api makes the responses).

Small and self-contained, with the site's stylesheet; every value is escaped. A refused launch's page names its
check twice: for a person (`<strong>nonce</strong>: this launch was used already`) and for tests and support
(`data-check="nonce"`).
"""

from __future__ import annotations

from html import escape

from server.core.answers import Page

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


def page(title: str, body_html: str, status: int = 200, attrs: str = "") -> Page:
    """A small page: `title` (text, escaped here) and `body_html` (HTML, escaped by the caller)."""
    html = TEMPLATE.format(title=escape(title), attrs=attrs, body=body_html)
    return Page(html, status)


def error_page(check: str, message: str, status: int = 400) -> Page:
    """The page of a refused launch or login: `check` the failed check's name, `message` what went wrong."""
    body = (
        "<h1>The launch was refused</h1>\n"
        f'<p class="message" data-kind="error"><strong>{escape(check)}</strong>: {escape(message, quote=False)}</p>\n'
        "<p>Open the link again from your course. If this page comes back, tell your instructor or the "
        "administrator of this server what it says.</p>"
    )
    return page("Launch refused", body, status, f' class="lti-refused" data-check="{escape(check, quote=True)}"')


def deep_link_form(return_url: str, jwt: str, summary: str = "") -> Page:
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


def storage_put_page(target: str, origin: str, state: str, nonce: str, next_url: str) -> Page:
    """The login's page when the platform offers LTI Platform Storage: state and nonce put into the platform's
    page (web/js/lti_storage.js), then on to the platform's authentication request."""
    attrs = {"mode": "put", "target": target, "origin": origin, "state": state, "nonce": nonce, "next": next_url}
    data = " ".join(f'data-{k}="{escape(v, quote=True)}"' for k, v in attrs.items())
    body = (
        f'<p id="lti-storage" {data}>Signing you in…</p>\n'
        '<p id="lti-storage-status" class="message" role="status"></p>\n'
        f'<noscript><p><a href="{escape(next_url, quote=True)}">Continue</a></p></noscript>\n'
        '<script src="/js/lti_storage.js"></script>'
    )
    return page("Signing in", body)


def storage_check_page(target: str, origin: str, state: str, continuation: str) -> Page:
    """The launch's page when its login put the state into the platform's storage and no cookie came back: the
    state read there (web/js/lti_storage.js) must be this launch's before it opens (the form, POST /lti/continue)."""
    attrs = {"mode": "get", "target": target, "origin": origin, "state": state}
    data = " ".join(f'data-{k}="{escape(v, quote=True)}"' for k, v in attrs.items())
    body = (
        f'<p id="lti-storage" {data}>Checking the sign-in with your learning platform…</p>\n'
        '<p id="lti-storage-status" class="message" role="status"></p>\n'
        '<form id="lti-continue" method="post" action="/lti/continue" hidden>'
        f'<input type="hidden" name="id" value="{escape(continuation, quote=True)}"></form>\n'
        '<script src="/js/lti_storage.js"></script>'
    )
    return page("Checking the sign-in", body)


def new_window_page(login_url: str) -> Page:
    """The login's page for a browser that keeps no cookie for the tool inside the platform's page (and no
    Platform Storage was offered): the tool opens in a window of its own, where the same login sets its cookie
    first (a launch is accepted only by the browser that holds its state's cookie)."""
    body = (
        "<h1>Open the tool in a new window</h1>\n"
        "<p>Your browser keeps no cookie for this tool inside the course's page, and the sign-in needs one. "
        "Open it in a window of its own: you are signed in there the same way.</p>\n"
        f'<p><a id="lti-new-window" class="button" href="{escape(login_url, quote=True)}" target="_blank" '
        'rel="noopener">Open in a new window</a></p>'
    )
    return page("Open in a new window", body, 200, ' class="lti-page" data-check="cookie"')
