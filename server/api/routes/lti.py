"""LTI 1.3 (docs/lti.md): a learning platform launches the tool inside a course.

- `GET /lti/jwks`: the tool's public keys (platforms check its client assertions and deep-linking answers).
- `GET|POST /lti/login`: the platform's third-party login initiation: the tool makes a one-time `state` and
  `nonce` (server-side), sets the state's cookie and sends the browser to the platform's auth URL.
- `POST /lti/launch`: the platform form-posts the signed id_token and the state back; the launch is checked
  (server/lti/launch.py) and handed to the app's launch handler; a refused one gets a page naming its check.
- `POST|GET /api/lti/platforms`, `DELETE /api/lti/platforms/{id}`: registered platforms, the server admin's
  (the instructor token).

The login and the launch are cross-site by design (the LMS posts them, often inside an iframe where third-party
cookies are blocked): the state's cookie is checked when it comes back, and the server-side one-time state
stands when it does not.
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
from server.api.deps import LtiDep, SettingsDep, require_instructor
from server.api.errors import ApiError
from server.lti.launch import LaunchError, auth_request_url, verify_launch
from server.lti.pages import error_page, storage_check_page, storage_put_page
from server.lti.tool import origin

log = logging.getLogger("server.lti")
router = APIRouter()
STATE_AGE = 600  # seconds a login's state is good for (and its cookie's Max-Age)
STORAGE_TARGET = re.compile(r"_parent|[A-Za-z0-9_-]{1,64}")  # Platform Storage's frame: the parent, or a name
MAX_FIELD = 16384  # characters of a login's or launch's parameter (an id_token is a few KB)


def state_cookie(state: str) -> str:
    return f"lti_state_{state[:8]}"


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
    state, nonce = await run_in_threadpool(lti.store.new_login, platform["id"], target, lti.clock(), storage)
    url = auth_request_url(
        platform, login_hint=login_hint, lti_message_hint=p.get("lti_message_hint"), state=state, nonce=nonce,
        redirect_uri=str(request.url_for("lti_launch")), client_id=platform["client_id"],
    )  # fmt: skip
    if storage:  # LTI Platform Storage: state and nonce kept in the platform's page too (no cookie needed)
        response = respond(storage_put_page(storage, platform_origin, state, nonce, url))
    else:
        response = RedirectResponse(url, status_code=302, headers={"Cache-Control": "no-store"})
    response.headers.append(
        "set-cookie",
        f"{state_cookie(state)}={state}; Max-Age={STATE_AGE}; Path=/lti/; Secure; HttpOnly; SameSite=None; Partitioned",
    )
    return response


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
    cookie = request.cookies.get(state_cookie(state))
    if cookie is not None and not hmac.compare_digest(cookie.encode(), state.encode()):
        return refused(LaunchError("state", "the launch's state is not the one this browser's login was given"))
    try:
        launch = await run_in_threadpool(
            verify_launch, p.get("id_token", ""), store=lti.store, jwks=lti.jwks, state_row=row, now=now,
            leeway=settings.lti_leeway,
        )  # fmt: skip
    except LaunchError as e:
        return refused(e)
    await run_in_threadpool(lti.learn_origins, launch)  # before the answer's headers name who may frame it
    platform_origin = origin(launch.platform["auth_url"])
    if row.get("storage_target") and cookie is None and platform_origin:
        # no cookie came back (the platform's frame keeps none), and the login put its state into the platform's
        # storage: the launch opens once the page has read the same state there (POST /lti/continue)
        response = respond(storage_check_page(row["storage_target"], platform_origin, state, lti.hold(launch)))
    else:
        response = respond(await run_in_threadpool(lti.handler.launched, launch, str(request.base_url)))
    response.headers.append(
        "set-cookie", f"{state_cookie(state)}=; Max-Age=0; Path=/lti/; Secure; HttpOnly; SameSite=None; Partitioned"
    )
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


@router.post("/api/lti/platforms", status_code=201, tags=["lti"], dependencies=[Depends(require_instructor)])
async def register_platform(body: PlatformIn, lti: LtiDep) -> dict:
    """Register (or update) an LTI 1.3 platform: 422 naming the field of a wrong value."""
    platform = await run_in_threadpool(lambda: lti.store.register(**body.model_dump(), now=lti.clock()))
    lti.refresh()
    return platform


@router.get("/api/lti/platforms", tags=["lti"], dependencies=[Depends(require_instructor)])
async def list_platforms(lti: LtiDep) -> list[dict]:
    return await run_in_threadpool(lti.store.platforms)


@router.delete("/api/lti/platforms/{pid}", status_code=204, tags=["lti"], dependencies=[Depends(require_instructor)])
async def remove_platform(pid: str, lti: LtiDep) -> Response:
    if not await run_in_threadpool(lti.store.remove, pid):
        raise ApiError(404, [{"path": "id", "message": f"no platform {pid[:40]!r}"}])
    lti.refresh()
    return Response(status_code=204)
