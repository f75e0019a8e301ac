"""LTI 1.3 (docs/lti.md): a learning platform launches the tool inside a course.

- `GET /lti/jwks`: the tool's public keys (platforms check its client assertions and deep-linking answers).
- `GET|POST /lti/login`: the platform's third-party login initiation: the tool makes a one-time `state` and
  `nonce` (server-side), sets the state's cookie and sends the browser to the platform's auth URL.
- `POST /lti/launch`: the platform form-posts the signed id_token and the state back; the launch is checked
  (server/lti/launch.py) and handed to the app's launch handler; a refused one gets a page naming its check.
- `POST|GET /api/lti/platforms`, `DELETE /api/lti/platforms/{id}`: registered platforms, the server admin's
  (the instructor token).

The login and the launch are cross-site by design (the LMS posts them, often inside an iframe where third-party
cookies are blocked). A launch is the browser's that started its login: its state must be the one of the state
cookie (one cookie, `lti_state`). Without that cookie a launch opens only through LTI Platform Storage (the state
read back from the platform's page); so a login without storage first checks that the browser keeps the tool's
cookie inside the platform's page, and where it does not, offers to open the tool in a window of its own (where
the login sets its cookie first).
"""

from __future__ import annotations

import hmac
import logging
import re

from fastapi import APIRouter, Depends, Request, Response
from fastapi.responses import JSONResponse, RedirectResponse
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool

from server.api.answers import respond
from server.api.deps import LtiDep, SettingsDep, client_address, require_instructor
from server.api.errors import ApiError
from server.core.clients import address_key
from server.lti.launch import LaunchError, auth_request_url, check_service_urls, verify_launch
from server.lti.pages import error_page, new_window_page, storage_check_page, storage_put_page
from server.lti.store import TooManyLogins
from server.lti.tool import origin

log = logging.getLogger("server.lti")
router = APIRouter()
STATE_AGE = 600  # seconds a login's state is good for (and its cookie's Max-Age)
STORAGE_TARGET = re.compile(r"_parent|[A-Za-z0-9_-]{1,64}")  # Platform Storage's frame: the parent, or a name
MAX_FIELD = 16384  # characters of a login's or launch's parameter (an id_token is a few KB)


STATE_COOKIE = "lti_state"  # the one state cookie: a launch's state must be the one its browser's login was given
CHECK_COOKIE = "lti_check"  # set by the login's first step: does this browser keep the tool's cookies here?
CHECK = "lti_cookie_check"  # the login's second step (its query parameter)
LOGIN_PARAMS = ("iss", "login_hint", "target_link_uri", "lti_message_hint", "client_id", "lti_deployment_id",
                "lti_storage_target")  # fmt: skip


async def _params(request: Request) -> dict[str, str]:
    """The request's parameters: its query, and its form for a POST (text values only, bounded)."""
    params = dict(request.query_params)
    if request.method == "POST":
        form = await request.form(max_files=0, max_fields=64)
        params |= {k: v for k, v in form.items() if isinstance(v, str)}
    return {k: v for k, v in params.items() if len(v) <= MAX_FIELD}


def refused(error: LaunchError) -> Response:
    log.info("LTI launch refused: %s", error)
    return respond(error_page(error.check, error.message, error.status))


# -- the launch ----------------------------------------------------------------------------------------


@router.get("/lti/jwks", include_in_schema=False)
async def tool_jwks(lti: LtiDep) -> JSONResponse:
    return JSONResponse(lti.keys.jwks(), headers={"Cache-Control": "max-age=300"})


def _cookie(name: str, value: str, age: int) -> str:
    return f"{name}={value}; Max-Age={age}; Path=/lti/; Secure; HttpOnly; SameSite=None; Partitioned"


@router.api_route("/lti/login", methods=["GET", "POST"], include_in_schema=False)
async def lti_login(request: Request, lti: LtiDep) -> Response:
    p = await _params(request)
    iss, login_hint, target = p.get("iss"), p.get("login_hint"), p.get("target_link_uri")
    if not iss:
        return refused(LaunchError("platform", "the login names no platform (iss)"))
    platform = await run_in_threadpool(lti.store.find, iss, p.get("client_id"))
    if platform is None:
        client = f" and client id '{p['client_id']}'" if p.get("client_id") else ""
        return refused(LaunchError("platform", f"no platform is registered with issuer '{iss}'{client}"))
    if not login_hint or not target:
        return refused(LaunchError("login", "the login carries no login_hint or no target_link_uri"))
    deployment = p.get("lti_deployment_id")
    if deployment and deployment not in platform["deployment_ids"]:
        return refused(LaunchError("deployment_id", f"deployment '{deployment}' is not registered for {iss}"))
    storage = p.get("lti_storage_target")
    if storage is not None and not STORAGE_TARGET.fullmatch(storage):
        return refused(LaunchError("login", "lti_storage_target is not a frame's name ('_parent' or a name)"))
    platform_origin = origin(platform["auth_url"])
    storage = storage if platform_origin else None
    login = {k: v for k, v in p.items() if k in LOGIN_PARAMS}
    if not storage and p.get(CHECK) != "1":
        # no Platform Storage: the state will be checked by its cookie alone, so the browser must keep one here;
        # a cookie is set, and the login comes back to look for it (GET /lti/login?...&lti_cookie_check=1)
        again = str(request.url_for("lti_login").include_query_params(**login, **{CHECK: "1"}))
        response = RedirectResponse(again, status_code=302, headers={"Cache-Control": "no-store"})
        response.headers.append("set-cookie", _cookie(CHECK_COOKIE, "1", STATE_AGE))
        return response
    if not storage and request.cookies.get(CHECK_COOKIE) != "1":
        # a browser that keeps no cookie for the tool inside the platform's page: the tool opens in a window of
        # its own, where the same login sets its cookie first
        alone = str(request.url_for("lti_login").include_query_params(**login))
        return respond(new_window_page(alone))
    try:
        state, nonce = await run_in_threadpool(
            lti.store.new_login, platform["id"], target, lti.clock(), storage, address_key(client_address(request))
        )
    except TooManyLogins as e:
        log.warning("LTI login refused: %s", e.message)
        response = respond(error_page("login", e.message, 429))
        response.headers["Retry-After"] = str(e.retry_after)
        return response
    url = auth_request_url(
        platform, login_hint=login_hint, lti_message_hint=p.get("lti_message_hint"), state=state, nonce=nonce,
        redirect_uri=str(request.url_for("lti_launch")), client_id=platform["client_id"],
    )  # fmt: skip
    if storage and platform_origin:  # LTI Platform Storage: state and nonce kept in the platform's page too
        response = respond(storage_put_page(storage, platform_origin, state, nonce, url))
    else:
        response = RedirectResponse(url, status_code=302, headers={"Cache-Control": "no-store"})
    response.headers.append("set-cookie", _cookie(STATE_COOKIE, state, STATE_AGE))  # (lti_check left to expire:
    return response  # another tab's login may be between its two steps)


@router.post("/lti/launch", include_in_schema=False, name="lti_launch")
async def lti_launch(request: Request, lti: LtiDep, settings: SettingsDep) -> Response:
    p = await _params(request)
    if p.get("error"):  # the platform's OIDC error answer (login_required, ...)
        why = p.get("error_description") or p["error"]
        return refused(LaunchError("login", f"the platform did not authenticate the launch: {why}"))
    state = p.get("state")
    if not state:
        return refused(LaunchError("state", "the launch carries no state"))
    now = lti.clock()
    row = await run_in_threadpool(lti.store.take_login, state, now, STATE_AGE)
    if row is None:
        message = "this launch's login is unknown, used already or older than 10 minutes; open the link again"
        return refused(LaunchError("state", message))
    cookie = request.cookies.get(STATE_COOKIE)
    if cookie is not None and not hmac.compare_digest(cookie.encode(), state.encode()):
        return refused(LaunchError("state", "the launch's state is not the one this browser's login was given"))
    storage = row.get("storage_target")
    if cookie is None and not storage:  # only the browser that started the login may finish it
        message = ("this browser did not send back the cookie of its sign-in, and the platform keeps no copy of it "
                   "(Platform Storage): open the link again from the course")  # fmt: skip
        return refused(LaunchError("state", message))
    try:
        launch = await run_in_threadpool(
            verify_launch, p.get("id_token", ""), store=lti.store, jwks=lti.jwks, state_row=row, now=now,
            leeway=settings.lti_leeway,
        )  # fmt: skip
        check_service_urls(launch)
    except LaunchError as e:
        return refused(e)
    await run_in_threadpool(lti.learn_origins, launch)  # before the answer's headers name who may frame it
    platform_origin = origin(launch.platform["auth_url"])
    if storage and cookie is None and platform_origin:
        # no cookie came back (the platform's frame keeps none), and the login put its state into the platform's
        # storage: the launch opens once the page has read the same state there (POST /lti/continue)
        response = respond(storage_check_page(storage, platform_origin, state, lti.hold(launch)))
    else:
        response = respond(await run_in_threadpool(lti.handler.launched, launch, str(request.base_url)))
    response.headers.append("set-cookie", _cookie(STATE_COOKIE, "", 0))
    return response


@router.post("/lti/continue", include_in_schema=False)
async def lti_continue(request: Request, lti: LtiDep) -> Response:
    """A launch checked against the platform's storage (web/js/lti_storage.js): opened now, once."""
    form = await request.form(max_files=0, max_fields=4)
    launch = lti.take(str(form.get("id") or "")[:64])
    if launch is None:
        message = "this sign-in was opened already, or waited too long: open the link again"
        return refused(LaunchError("state", message))
    return respond(await run_in_threadpool(lti.handler.launched, launch, str(request.base_url)))


# -- platforms (the server admin's) ------------------------------------------------------------------------


class PlatformIn(BaseModel):
    issuer: str = Field(description="the platform's issuer (the id_token's iss), an https URL")
    client_id: str = Field(description="the client id the platform gave this tool")
    auth_url: str = Field(description="the platform's OIDC authentication request URL")
    token_url: str = Field(description="the platform's OAuth 2 access token URL")
    jwks_url: str = Field(description="the platform's public keyset URL")
    deployment_ids: list[str] = Field(default_factory=list, description="deployment ids its launches may carry")
    name: str = Field("", description="a name to show")
    service_origins: list[str] = Field(
        default_factory=list, description="further origins of its services (a hosted Canvas's school address)"
    )
    trust_emails: bool = Field(False, description="a launch's email identifies the roster student of that email")
    allow_private: bool = Field(False, description="accept URLs on loopback, link-local or private addresses")


@router.post("/api/lti/platforms", status_code=201, tags=["lti"], dependencies=[Depends(require_instructor)])
async def register_platform(body: PlatformIn, lti: LtiDep) -> dict:
    """Register (or update) an LTI 1.3 platform: 422 naming the field of a wrong value."""
    platform = await run_in_threadpool(lambda: lti.store.register(**body.model_dump(), now=lti.clock()))
    lti.refresh()
    return dict(platform)  # a plain dict: FastAPI makes the return annotation the response model


@router.get("/api/lti/platforms", tags=["lti"], dependencies=[Depends(require_instructor)])
async def list_platforms(lti: LtiDep) -> list[dict]:
    return [dict(p) for p in await run_in_threadpool(lti.store.platforms)]


@router.delete("/api/lti/platforms/{pid}", status_code=204, tags=["lti"], dependencies=[Depends(require_instructor)])
async def remove_platform(pid: str, lti: LtiDep) -> Response:
    if not await run_in_threadpool(lti.store.remove, pid):
        raise ApiError(404, [{"path": "id", "message": f"no platform {pid[:40]!r}"}])
    lti.refresh()
    return Response(status_code=204)
