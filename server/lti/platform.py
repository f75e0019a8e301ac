"""A small LTI 1.3 platform (an LMS), served for real on 127.0.0.1 by uvicorn in a thread: what `python -m
server.lti try` plays an LMS with (server/lti/trial.py), and the tests' platform (tests/lti_platform.py imports it
from here: one copy). It never serves beyond loopback.

`Platform` has its own RSA key and serves what a tool talks to: its key set (`GET /jwks`, counted), the OIDC
authentication request (`GET /auth`, recorded), access tokens (`POST /token`: the client assertion checked
against the TOOL's key set), Assignment and Grade Services (line items per context, scores: recorded, with the
strictly increasing timestamps Canvas and the specification require; `down` answers 503), Names and Role
Provisioning (`GET /memberships/{context}`, paged by `?limit=`), and a deep-linking return URL that verifies the
tool's answer. `launch_token` signs the id_token of a launch with every claim a real one carries; `do_launch`
goes through the whole OIDC flow as a browser does. For a person at a browser: `person(hint, ...)` names a
launch that `GET /start/<hint>` begins (the tool's login, then an authentication answer that posts itself),
`GET /` lists them, `GET /gradebook` shows the scores received, and `place` puts a deep link's content item in
the course (a resource link and its gradebook column).

It is a plain ASGI app (no web framework: only server/api speaks HTTP through one) served by `LoopbackServer`
(server/lti/loopback.py); its services (tokens, AGS, NRPS, the deep-linking return) are
server/lti/platform_services.py's.
"""

from __future__ import annotations

import html
import json
import re
import secrets
import time
from collections.abc import Callable
from urllib.parse import parse_qs, urlencode, urlsplit

import httpx
from joserfc import jwt
from joserfc.jwk import RSAKey

from server.lti.loopback import Answer, LoopbackServer, Request, free_port, routed_app
from server.lti.platform_services import (
    AGS_CLAIM,
    AGS_SCOPES,
    CONTEXT,
    DL,
    LEARNER,
    LTI,
    PAGE,
    PlatformServices,
    member,
)


def new_key() -> RSAKey:
    key = RSAKey.generate_key(2048, {"alg": "RS256", "use": "sig"}, private=True)
    key.ensure_kid()
    return key


class Platform(PlatformServices):
    """An LMS on loopback. `tool_jwks_url` (the tool's key set) must be set before tokens are asked for."""

    def __init__(self, client_id: str = "tool-client-1", deployment_id: str = "deployment-1", name: str = "Test LMS"):
        self.port = free_port()
        self.url = self.issuer = f"http://127.0.0.1:{self.port}"
        self.client_id, self.deployment_id, self.name = client_id, deployment_id, name
        self.key = new_key()
        self.keys = [self.key]  # the published key set (a test may rotate)
        self.tool_jwks_url: str | None = None
        self.jwks_hits = 0  # GET /jwks
        self.auth_requests: list[dict] = []  # GET /auth's query parameters
        self.token_requests: list[dict] = []  # POST /token's forms (the granted scope added)
        self.tokens: dict[str, set[str]] = {}  # access token -> its scopes
        self.scores: list[dict] = []  # every score accepted, with its line item's id ("lineitem")
        self.down = False  # the score endpoint answers 503
        self.refuse: tuple[int, str] | None = None  # the score endpoint answers (HTTP status, OAuth-style error code)
        self.line_items: dict[str, dict] = {}  # id -> line item (its "context" key: the context's id)
        self.members: dict[str, list[dict]] = {"course-1": [member(i) for i in range(5)]}
        self.deep_links: list[dict] = []  # the content items of each verified deep-linking answer
        self.last: dict = {}  # the last do_launch's state, nonce, id_token, cookie
        self.launches: dict[str, dict] = {}  # login_hint -> launch_token's arguments (a browser's launch, `person`)
        self.links: dict[str, dict] = {}  # resource link id -> its launch arguments (`place`)
        self.auto_launch: dict | None = None  # launch_token's arguments: GET /auth answers a self-posting launch
        self.line_items["li-1"] = {"id": f"{self.url}/lineitems/li-1", "label": "Ray trees", "scoreMaximum": 10,
                                   "resourceLinkId": "link-1", "context": "course-1"}  # fmt: skip
        self.server = LoopbackServer(routed_app(self._routes()), self.port)

    # -- running ------------------------------------------------------------------------------------

    def start(self) -> Platform:
        self.server.start()
        return self

    def stop(self) -> None:
        self.server.stop()

    def __enter__(self) -> Platform:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def tool_url(self) -> str | None:
        """The tool's base URL (from its key set's)."""
        return self.tool_jwks_url.removesuffix("/lti/jwks") if self.tool_jwks_url else None

    @property
    def auth_url(self) -> str:
        return self.url + "/auth"

    @property
    def jwks_url(self) -> str:
        return self.url + "/jwks"

    def registration(self, **more) -> dict:
        """The values a tool registers this platform with (LtiStore.register's keywords, and the API's body):
        `allow_private`, since it is on 127.0.0.1; `more` adds or replaces some (trust_emails=True)."""
        return dict(issuer=self.issuer, client_id=self.client_id, auth_url=self.auth_url, token_url=self.token_url,
                    jwks_url=self.jwks_url, deployment_ids=[self.deployment_id], name=self.name,
                    allow_private=True) | more  # fmt: skip

    # -- launches -------------------------------------------------------------------------------------

    def launch_token(
        self, *, nonce: str, sub: str = "student-1", roles: list[str] | None = None, context: dict | None = None,
        resource_link: dict | None = None, message_type: str = "LtiResourceLinkRequest",
        deployment_id: str | None = None, custom: dict | None = None, ags: bool = True, nrps: bool = True,
        deep_linking: dict | None = None, overrides: dict | None = None, drop: list[str] | None = None,
        key: RSAKey | None = None, kid: str | None = None, now: float | None = None,
    ) -> str:  # fmt: skip
        """An id_token as a platform signs it, with every claim a real launch carries; `overrides` replace or add
        claims, `drop` removes some, `key` signs with another key (a bad signature), `kid` names another key."""
        now = time.time() if now is None else now
        context = CONTEXT if context is None else context
        link = resource_link or {"id": "link-1", "title": "Ray trees", "description": "Whitted's ray trees"}
        claims = {
            "iss": self.issuer,
            "aud": self.client_id,
            "azp": self.client_id,
            "sub": sub,
            "exp": int(now) + 300,
            "iat": int(now),
            "nonce": nonce,
            "name": "Ada Lovelace",
            "given_name": "Ada",
            "family_name": "Lovelace",
            "email": "ada@example.edu",
            LTI + "message_type": message_type,
            LTI + "version": "1.3.0",
            LTI + "deployment_id": deployment_id or self.deployment_id,
            LTI + "target_link_uri": "https://tool.example.edu/lti/launch",
            LTI + "roles": roles if roles is not None else [LEARNER],
            LTI + "context": {**context, "type": ["http://purl.imsglobal.org/vocab/lis/v2/course#CourseOffering"]},
            LTI + "custom": custom or {},
            LTI + "launch_presentation": {"document_target": "iframe", "locale": "en"},
            LTI + "tool_platform": {"guid": "test-lms", "name": self.name, "product_family_code": "test"},
        }
        if message_type == "LtiResourceLinkRequest":
            claims[LTI + "resource_link"] = link
        if deep_linking is not None or message_type == "LtiDeepLinkingRequest":
            claims[DL + "deep_linking_settings"] = deep_linking or {
                "deep_link_return_url": self.url + "/deep_link_return",
                "accept_types": ["ltiResourceLink"],
                "accept_presentation_document_targets": ["iframe", "window"],
                "accept_multiple": True,
                "data": "opaque-data-1",
            }
        if ags:
            cid = context.get("id", "course-1")
            claims["https://purl.imsglobal.org/spec/lti-ags/claim/endpoint"] = {
                "scope": AGS_SCOPES,
                "lineitems": f"{self.url}/lineitems?context={cid}",
                "lineitem": f"{self.url}/lineitems/li-1?context={cid}",
            }
        if nrps:
            claims["https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice"] = {
                "context_memberships_url": f"{self.url}/memberships/{context.get('id', 'course-1')}",
                "service_versions": ["2.0"],
            }
        claims |= overrides or {}
        for name in drop or ():
            claims.pop(name, None)
        signer = key or self.key
        header = {"alg": "RS256", "kid": kid or signer.kid, "typ": "JWT"}
        return jwt.encode(header, claims, signer, algorithms=["RS256"])

    def do_launch(
        self, client: httpx.Client, tool_base: str, *, method: str = "GET", login: dict | None = None,
        token: str | None = None, state: str | None = None, cookie: bool = True, **token_args,
    ) -> httpx.Response:  # fmt: skip
        """The OIDC flow as a browser goes through it: the tool's /lti/login (GET or POST), the redirect to this
        platform's /auth (recorded; state and nonce read from it), then the id_token (`launch_token(**token_args)`,
        or `token`) and the state (or `state`) posted to the tool's /lti/launch with the state's cookie (a browser
        sends it: 127.0.0.1 is a secure context; `cookie=False`: lost between the login and the launch). The
        login's check that the browser keeps the tool's cookie is passed (the check cookie sent back). The
        launch's response."""
        params = {"iss": self.issuer, "login_hint": "user-hint-1", "target_link_uri": tool_base + "/lti/launch",
                  "lti_message_hint": "message-hint-1", "client_id": self.client_id,
                  "lti_deployment_id": self.deployment_id} | (login or {})  # fmt: skip
        if method == "GET":
            r = client.get(tool_base + "/lti/login", params=params)
        else:
            r = client.post(tool_base + "/lti/login", data=params)
        assert r.status_code == 302, r.text
        if "lti_cookie_check=1" in r.headers["location"]:  # the login looks for its cookie (a browser keeps it)
            check = {"Cookie": "; ".join(f"{k}={v}" for k, v in cookies_of(r).items() if v)}
            r = client.get(r.headers["location"], headers=check)
            assert r.status_code == 302, r.text
        auth = client.get(r.headers["location"])
        assert auth.status_code == 200, auth.text
        query = self.auth_requests[-1]
        jar = {k: v for k, v in cookies_of(r).items() if v}
        token = token or self.launch_token(nonce=query["nonce"], **token_args)
        self.last = {"state": query["state"], "nonce": query["nonce"], "id_token": token, "cookies": jar}
        headers = {"Cookie": "; ".join(f"{k}={v}" for k, v in jar.items())} if cookie and jar else {}
        form = {"id_token": token, "state": state or query["state"]}
        return client.post(query["redirect_uri"], data=form, headers=headers)

    # -- launches an admin opens in a browser (python -m server.lti try) ---------------------------------

    def person(self, hint: str, **launch) -> str:
        """A person of this LMS whom a browser can launch the tool as: `start_url(hint)` starts the tool's login
        with `hint` as its login_hint, and the authentication answer then posts `launch_token(**launch)`."""
        self.launches[hint] = launch
        return self.start_url(hint)

    def start_url(self, hint: str) -> str:
        return f"{self.url}/start/{hint}"

    def place(self, item: dict, link_id: str | None = None) -> dict:
        """A content item a deep-linking answer brought, placed in the course as an LMS does: a resource link
        (its id, title and custom parameters) and, if the item asks for one, its gradebook column (a line item
        of its points). The launch arguments of that link (`launch_token`'s resource_link, custom, overrides)."""
        link_id = link_id or "link-" + secrets.token_hex(4)
        link = {"id": link_id, "title": item.get("title", "")}
        args: dict = {"resource_link": link, "custom": item.get("custom") or {}}
        if "lineItem" in item:
            lid = "li-" + secrets.token_hex(4)
            self.line_items[lid] = {**item["lineItem"], "id": f"{self.url}/lineitems/{lid}", "resourceLinkId": link_id,
                                    "context": CONTEXT["id"]}  # fmt: skip
            args["overrides"] = {AGS_CLAIM: {"scope": AGS_SCOPES, "lineitems": f"{self.url}/lineitems?context="
                                             f"{CONTEXT['id']}", "lineitem": self.line_items[lid]["id"]}}  # fmt: skip
        self.links[link_id] = args
        return args

    # -- the platform's app ------------------------------------------------------------------------------

    def _routes(self) -> list[tuple[str, re.Pattern, Callable]]:
        r = [
            ("GET", "/", self._home),
            ("GET", "/jwks", self._jwks),
            ("GET", "/auth", self._auth),
            ("GET", "/start/(?P<hint>[\\w.-]+)", self._start),
            ("GET", "/course-page", self._course_page),
            ("GET", "/gradebook", self._gradebook),
            ("POST", "/token", lambda req: self._token(req.form())),
            ("GET", "/lineitems", self._line_items),
            ("POST", "/lineitems", self._new_line_item),
            ("GET", "/lineitems/(?P<lid>[^/]+)", self._line_item),
            ("POST", "/lineitems/(?P<lid>[^/]+)/scores", self._scores),
            ("GET", "/memberships/(?P<context>[^/]+)", self._memberships),
            ("POST", "/deep_link_return", self._deep_link_return),
        ]
        return [(method, re.compile(pattern + "$"), handler) for method, pattern, handler in r]

    def _home(self, req: Request) -> Answer:
        """The LMS's course page for a person: the tool's links as each person it knows opens them."""
        items = "".join(f'<li><a href="/start/{html.escape(h)}">{html.escape(h.replace("-", " "))}</a></li>'
                        for h in self.launches)  # fmt: skip
        return Answer.html(
            f"{PAGE}<title>{html.escape(self.name)}</title><h1>{html.escape(self.name)}: "
            f"{CONTEXT['title']}</h1><p>Open the tool as:</p><ul>{items}</ul>"
            '<p><a href="/gradebook">The gradebook</a>: the grades the tool sent.</p></html>'
        )

    def _jwks(self, req: Request) -> Answer:
        self.jwks_hits += 1
        return Answer.json({"keys": [k.as_dict(private=False) | {"alg": "RS256", "use": "sig"} for k in self.keys]})

    def _start(self, req: Request, hint: str) -> Answer:
        """A browser's launch of the tool as the person `hint`: to the tool's login (OIDC initiation)."""
        if hint not in self.launches or self.tool_url is None:
            return Answer.json({"error": f"no person {hint!r}"}, 404)
        params = {
            "iss": self.issuer,
            "login_hint": hint,
            "target_link_uri": self.tool_url + "/lti/launch",
            "lti_message_hint": hint,
            "client_id": self.client_id,
            "lti_deployment_id": self.deployment_id,
        }
        return Answer.redirect(self.tool_url + "/lti/login?" + urlencode(params))

    def _auth(self, req: Request) -> Answer:
        query = req.query
        self.auth_requests.append(query)
        launch = self.launches.get(query.get("login_hint", "")) or self.auto_launch
        if launch is None:
            return Answer.json({"received": query})
        # as a browser meets a real platform: a form that posts the signed launch back at once
        token = self.launch_token(nonce=query["nonce"], **launch)
        return Answer.html(
            f'<form id="f" method="post" action="{html.escape(query["redirect_uri"])}">'
            f'<input type="hidden" name="id_token" value="{token}">'
            f'<input type="hidden" name="state" value="{html.escape(query["state"])}"></form>'
            # posted at once, or once the course page lets it go (`hold`: a test does something in between)
            "<script>const go = () => (window.parent.holdLaunch ? setTimeout(go, 50)"
            ' : document.getElementById("f").submit()); go();</script>'
        )

    def _course_page(self, req: Request) -> Answer:
        """The platform's page of a course: the tool in a frame (its login URL), and LTI Platform Storage for it
        (lti.put_data / lti.get_data by postMessage, from the tool's origin only; `tamper`: the state read back is
        another one; `hold`: the authentication answer waits until `holdLaunch` is false)."""
        tool, login = req.query.get("tool", ""), req.query.get("login", "")
        tamper, hold = int(req.query.get("tamper", 0)), int(req.query.get("hold", 0))
        script = (
            f"const store = {{}}; window.storageLog = []; window.holdLaunch = {bool(hold).__str__().lower()};"
            "window.addEventListener('message', (e) => {"
            f"  if (e.origin !== {json.dumps(tool)} || !e.data || !e.data.subject) return;"
            "  const m = e.data; window.storageLog.push(m.subject + ' ' + m.key);"
            "  if (m.subject === 'lti.put_data') store[m.key] = m.value;"
            f"  const value = m.subject === 'lti.get_data' && {int(tamper)} ? 'another' : store[m.key];"
            "  e.source.postMessage({subject: m.subject + '.response', message_id: m.message_id, key: m.key,"
            "                        value}, e.origin);"
            "});"
        )
        return Answer.html(
            f"<!doctype html><title>LMS course</title><script>{script}</script>"
            f'<h1>Rendering 101</h1><iframe name="tool" src="{html.escape(login)}" width="1000"'
            ' height="700"></iframe>'
        )

    def _gradebook(self, req: Request) -> Answer:
        """The grades the tool sent, as the LMS's gradebook shows them: each line item's scores."""
        rows = "".join(
            f"<tr><td>{html.escape(str(self.line_items.get(s['lineitem'], {}).get('label', s['lineitem'])))}</td>"
            f"<td>{html.escape(str(s.get('userId')))}</td><td>{s.get('scoreGiven')} / {s.get('scoreMaximum')}</td>"
            f"<td>{html.escape(str(s.get('gradingProgress')))}</td><td>{html.escape(str(s.get('timestamp')))}</td></tr>"
            for s in self.scores
        )
        return Answer.html(
            f"{PAGE}<title>Gradebook</title><h1>Gradebook of {CONTEXT['title']}</h1>"
            "<table><thead><tr><th>Column</th><th>Student</th><th>Score</th><th>Grading</th><th>Time</th></tr>"
            f"</thead><tbody>{rows}</tbody></table><p>{len(self.scores)} score(s) received.</p></html>"
        )


def cookies_of(r: httpx.Response) -> dict:
    """The cookies a response sets: name -> value ("" for one it ends)."""
    return {c.split("=", 1)[0]: c.split("=", 1)[1].split(";", 1)[0] for c in r.headers.get_list("set-cookie")}


def query_of(url: str) -> dict:
    return {k: v[0] for k, v in parse_qs(urlsplit(url).query).items()}
