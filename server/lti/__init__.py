"""LTI 1.3 and LTI Advantage, the tool's side (docs/lti.md): a learning platform (Canvas, Moodle, ...) launches
the service inside a course, and the service sends grades back and reads the course's members.

- `keys.py`      the tool's RSA key pair (its public JWKS, JWTs it signs)
- `store.py`     registered platforms, logins in flight (state, nonce), nonces seen, origins seen (SQLite)
- `launch.py`    the OIDC login's auth request, the platforms' JWKS (cached), the id_token's checks, `Launch`
- `roles.py`     LIS/LTI role URIs -> the course's role (instructor, ta, student)
- `services.py`  Advantage calls: access tokens, scores (AGS), line items, members (NRPS), deep-linking answers
- `handler.py`   what a verified launch opens: the `LaunchHandler` protocol and the default `EchoHandler`
- `pages.py`     the refused launch's HTML page, the deep-linking answer's form
- `http.py`      outbound answers read with a size bound
- `tool.py`      `LtiTool`, what the app holds as `app.state.lti`, and who may frame the tool's pages
- `command.py`   python -m server.lti register|list|remove|show-tool
"""
