"""The services of the LTI platform an LMS plays on loopback (server/lti/platform.py's `Platform`, which mixes
them in): access tokens (`POST /token`: the client assertion checked against the TOOL's key set), Assignment and
Grade Services (line items per context, scores: recorded, with the strictly increasing timestamps Canvas and the
specification require; `down` answers 503, `refuse` another refusal), Names and Role Provisioning
(`GET /memberships/{context}`, paged by `?limit=`), and a deep-linking return URL that verifies the tool's answer;
the LTI claims' and vocabularies' names they and the launches use.
"""

from __future__ import annotations

import html
import secrets
import time

import httpx
from joserfc import jwt
from joserfc.errors import JoseError
from joserfc.jwk import KeySet

from server.lti.loopback import Answer, Request

LTI = "https://purl.imsglobal.org/spec/lti/claim/"
DL = "https://purl.imsglobal.org/spec/lti-dl/claim/"
AGS = "https://purl.imsglobal.org/spec/lti-ags/scope/"
AGS_SCOPES = [AGS + "lineitem", AGS + "lineitem.readonly", AGS + "result.readonly", AGS + "score"]
NRPS_SCOPE = "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly"
LINEITEMS_TYPE = "application/vnd.ims.lis.v2.lineitemcontainer+json"
LINEITEM_TYPE = "application/vnd.ims.lis.v2.lineitem+json"
MEMBERS_TYPE = "application/vnd.ims.lti-nrps.v2.membershipcontainer+json"
LEARNER = "http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"
INSTRUCTOR = "http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"
AGS_CLAIM = "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint"
CONTEXT = {"id": "course-1", "label": "CS-R101", "title": "Rendering 101"}
PAGE = '<!doctype html><html lang="en"><link rel="icon" href="data:,">'  # the start of a page (no favicon asked)


class PlatformServices:
    """The service endpoints' handlers, on the platform's state (set by `Platform.__init__`)."""

    url: str
    issuer: str
    client_id: str
    deployment_id: str
    tool_jwks_url: str | None
    token_requests: list[dict]
    tokens: dict[str, set[str]]
    scores: list[dict]
    down: bool
    refuse: tuple[int, str] | None
    line_items: dict[str, dict]
    members: dict[str, list[dict]]
    deep_links: list[dict]

    @property
    def token_url(self) -> str:
        return self.url + "/token"

    def _line_items(self, req: Request) -> Answer:
        if error := self._refused(req, AGS + "lineitem", AGS + "lineitem.readonly"):
            return error
        context, link = req.query.get("context", "course-1"), req.query.get("resource_link_id")
        items = [i for i in self.line_items.values() if i["context"] == context]
        items = [i for i in items if link in (None, i.get("resourceLinkId"))]
        return Answer.json([public(i) for i in items], media_type=LINEITEMS_TYPE)

    def _new_line_item(self, req: Request) -> Answer:
        if error := self._refused(req, AGS + "lineitem"):
            return error
        lid = "li-" + secrets.token_hex(4)
        item = {**req.json(), "id": f"{self.url}/lineitems/{lid}", "context": req.query.get("context", "course-1")}
        self.line_items[lid] = item
        return Answer.json(public(item), 201, media_type=LINEITEM_TYPE)

    def _line_item(self, req: Request, lid: str) -> Answer:
        if error := self._refused(req, AGS + "lineitem", AGS + "lineitem.readonly"):
            return error
        if lid not in self.line_items:
            return Answer.json({"error": "not found"}, 404)
        return Answer.json(public(self.line_items[lid]), media_type=LINEITEM_TYPE)

    def _scores(self, req: Request, lid: str) -> Answer:
        if error := self._refused(req, AGS + "score"):
            return error
        if req.headers.get("content-type") != "application/vnd.ims.lis.v1.score+json":
            return Answer.json({"error": "unsupported content type"}, 415)
        if self.down:
            return Answer.json({"error": "down for maintenance"}, 503)
        if self.refuse is not None:
            return Answer.json({"error": self.refuse[1]}, self.refuse[0])
        if lid not in self.line_items:
            return Answer.json({"error": "not found"}, 404)
        score = req.json()
        before = [s for s in self.scores if s["lineitem"] == lid and s["userId"] == score.get("userId")]
        if before and score.get("timestamp", "") <= before[-1]["timestamp"]:  # same format: text order is time order
            return Answer.json({"error": "timestamp not later than the last score's"}, 409)
        self.scores.append({**score, "lineitem": lid})
        return Answer(204)

    def drop(self, context: str, user_id: str) -> dict:
        """A member leaves the LMS course (gone from its memberships, as a dropped student is): the member."""
        (gone,) = [m for m in self.members[context] if m["user_id"] == user_id]
        self.members[context].remove(gone)
        return gone

    def _memberships(self, req: Request, context: str) -> Answer:
        if error := self._refused(req, NRPS_SCOPE):
            return error
        limit, page = int(req.query.get("limit", 0)), int(req.query.get("page", 0))
        everyone = self.members.get(context, [])
        shown = everyone[page * limit : (page + 1) * limit] if limit else everyone
        headers = {}
        if limit and (page + 1) * limit < len(everyone):
            headers["Link"] = f'<{self.url}/memberships/{context}?limit={limit}&page={page + 1}>; rel="next"'
        body = {"id": req.url, "context": {"id": context}, "members": shown}
        return Answer.json(body, headers=headers, media_type=MEMBERS_TYPE)

    def _deep_link_return(self, req: Request) -> Answer:
        claims = self._tool_jwt(str(req.form().get("JWT", "")))
        assert claims["iss"] == self.client_id and claims["aud"] == self.issuer, claims
        assert claims[LTI + "message_type"] == "LtiDeepLinkingResponse", claims
        assert claims[LTI + "deployment_id"] == self.deployment_id and claims[LTI + "version"] == "1.3.0"
        self.deep_links.append(claims)
        titles = "".join(
            f"<li>{html.escape(str(i.get('title', '')))}</li>" for i in claims.get(DL + "content_items", [])
        )
        return Answer.html(f'{PAGE}<title>Added</title><p>content items received</p>'
                           f'<ul>{titles}</ul><p><a href="/">Back to the course</a></p></html>')  # fmt: skip

    def _tool_jwt(self, token: str) -> dict:
        """The claims of a JWT the tool signed, verified with the tool's published key set (fetched now)."""
        assert self.tool_jwks_url is not None, "set tool_jwks_url first"
        keys = KeySet.import_key_set(httpx.get(self.tool_jwks_url, timeout=5).json())
        return jwt.decode(token, keys, algorithms=["RS256"]).claims

    def _token(self, form: dict) -> Answer:
        def refuse(error: str, why: str) -> Answer:
            return Answer.json({"error": error, "error_description": why}, 401 if error == "invalid_client" else 400)

        if form.get("grant_type") != "client_credentials":
            return refuse("unsupported_grant_type", "expected client_credentials")
        if form.get("client_assertion_type") != "urn:ietf:params:oauth:client-assertion-type:jwt-bearer":
            return refuse("invalid_request", "expected a JWT client assertion")
        try:
            claims = self._tool_jwt(str(form.get("client_assertion", "")))
        except (JoseError, ValueError, httpx.HTTPError) as e:
            return refuse("invalid_client", f"the client assertion does not verify: {e}")
        aud = claims.get("aud")
        if claims.get("iss") != self.client_id or claims.get("sub") != self.client_id:
            return refuse("invalid_client", "iss and sub must be the client id")
        if self.token_url not in ([aud] if isinstance(aud, str) else aud or []):
            return refuse("invalid_client", "aud must be the token URL")
        if not isinstance(claims.get("exp"), int) or claims["exp"] <= time.time() or not claims.get("jti"):
            return refuse("invalid_client", "expired, or no jti")
        scopes = set(str(form.get("scope", "")).split()) & {*AGS_SCOPES, NRPS_SCOPE}
        token = secrets.token_urlsafe(24)
        self.tokens[token] = scopes
        self.token_requests.append({**form, "granted": sorted(scopes)})
        return Answer.json(
            {"access_token": token, "token_type": "Bearer", "expires_in": 3600, "scope": " ".join(sorted(scopes))}
        )

    def _refused(self, request: Request, *scopes: str) -> Answer | None:
        """401 without a known bearer token, 403 when it has none of `scopes`; None when it may."""
        scheme, _, token = request.headers.get("authorization", "").partition(" ")
        if scheme.lower() != "bearer" or token not in self.tokens:
            return Answer.json({"error": "invalid_token"}, 401)
        if not self.tokens[token] & set(scopes):
            return Answer.json({"error": "insufficient_scope"}, 403)
        return None


def member(i: int) -> dict:
    """The i-th member of the test course: an instructor first, then students."""
    return {
        "status": "Active",
        "name": f"Person {i}",
        "given_name": "Person",
        "family_name": str(i),
        "email": f"person{i}@example.edu",
        "user_id": f"user-{i}",
        "lis_person_sourcedid": f"sis-{i}",
        "roles": [INSTRUCTOR] if i == 0 else [LEARNER],
    }


def public(item: dict) -> dict:
    return {k: v for k, v in item.items() if k != "context"}
