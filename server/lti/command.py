"""python -m server.lti: the deployer's command line for LTI 1.3 (docs/lti.md). It works on the data directory's
database directly (--data-dir, else TRACER_DATA_DIR or ./data), so it runs beside a running server (which sees a
new platform within a minute, or at once when it is registered through POST /api/lti/platforms).

    python -m server.lti register --issuer URL --client-id ID --auth-url URL --token-url URL --jwks-url URL
        --deployment ID [--deployment ID2 ...] [--name NAME] [--service-origin URL ...] [--trust-emails]
        [--allow-private] [--data-dir DIR]
    python -m server.lti list [--data-dir DIR]
    python -m server.lti remove ID [--data-dir DIR]
    python -m server.lti rotate-key [--grace-hours 72] [--data-dir DIR]
    python -m server.lti show-tool --base https://tool.example.edu
    python -m server.lti try [--url URL --token TOKEN] [--keep]   (server/lti/trial.py: a pretend LMS on loopback)

`register` prints the platform's id on its first line, then what was registered; a wrong value is printed as
`field: message` lines (exit 1). `show-tool` prints the values to paste into the LMS, then Canvas's developer
key as JSON (everything after the line that starts with "Canvas developer key").
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from urllib.parse import urlsplit

from server.core.errors import DomainError
from server.lti import trial
from server.lti.keys import DEFAULT_GRACE_HOURS, ToolKeys
from server.lti.services import LINEITEM_READ_SCOPE, LINEITEM_SCOPE, NRPS_SCOPE, RESULT_READ_SCOPE, SCORE_SCOPE
from server.lti.store import LtiStore, PlatformRow, url_problem

TITLE = "Ray tracing for teaching"
DESCRIPTION = "Write scenes, watch them render, inspect ray trees; assignments graded and sent back to the course."
CANVAS_HEADER = "Canvas developer key (Developer Keys > + LTI Key > Method: Paste JSON):"


def tool_urls(base: str) -> dict[str, str]:
    """The tool's URLs under `base` (its public https address)."""
    base = base.rstrip("/")
    return {
        "login": base + "/lti/login",
        "launch": base + "/lti/launch",
        "jwks": base + "/lti/jwks",
        "deep_linking": base + "/lti/launch",
    }


def canvas_key(base: str) -> dict:
    """Canvas's developer key configuration (LTI 1.3), as pasted into "Method: Paste JSON"."""
    urls = tool_urls(base)
    launch = {"target_link_uri": urls["launch"]}
    placements = [
        {"placement": "course_navigation", "message_type": "LtiResourceLinkRequest", "text": TITLE, **launch},
        {"placement": "assignment_selection", "message_type": "LtiDeepLinkingRequest", "text": TITLE, **launch},
        {"placement": "link_selection", "message_type": "LtiDeepLinkingRequest", "text": TITLE, **launch},
    ]
    return {
        "title": TITLE,
        "description": DESCRIPTION,
        "oidc_initiation_url": urls["login"],
        "target_link_uri": urls["launch"],
        "public_jwk_url": urls["jwks"],
        "scopes": [LINEITEM_SCOPE, LINEITEM_READ_SCOPE, RESULT_READ_SCOPE, SCORE_SCOPE, NRPS_SCOPE],
        "extensions": [
            {
                "platform": "canvas.instructure.com",
                "domain": urlsplit(base).netloc,
                "tool_id": "raytrace-edu",
                "privacy_level": "public",
                "settings": {"text": TITLE, "placements": placements},
            }
        ],
        "custom_fields": {},
    }


def show_tool(base: str) -> str:
    urls = tool_urls(base)
    lines = [
        f"Login URL (OpenID Connect initiation): {urls['login']}",
        f"Launch URL (redirect URI, target link URI): {urls['launch']}",
        f"Public keyset URL (JWKS): {urls['jwks']}",
        f"Deep linking URL (content selection): {urls['deep_linking']}",
        "(deep linking requests, LtiDeepLinkingRequest, come to the launch URL too)",
        "",
        CANVAS_HEADER,
        json.dumps(canvas_key(base), indent=2),
    ]
    return "\n".join(lines)


def describe(p: PlatformRow) -> str:
    deployments = ", ".join(p["deployment_ids"]) or "none"
    name = f" ({p['name']})" if p["name"] else ""
    extra = f"  service origins: {p['service_origins']}" if p.get("service_origins") else ""
    emails = "  trusts emails" if p.get("trust_emails") else ""
    return f"{p['id']}  {p['issuer']}{name}  client id {p['client_id']}  deployments: {deployments}{extra}{emails}"


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m server.lti", description="LTI 1.3 platforms of this tool")
    sub = ap.add_subparsers(dest="command", required=True)
    reg = sub.add_parser("register", help="register (or update) a platform: an LMS and the client id it gave")
    reg.add_argument("--issuer", required=True, help="the platform's issuer (Canvas: https://canvas.instructure.com)")
    reg.add_argument("--client-id", required=True, help="the client id the platform gave this tool")
    reg.add_argument("--auth-url", required=True, help="the platform's OIDC authentication request URL")
    reg.add_argument("--token-url", required=True, help="the platform's access token URL")
    reg.add_argument("--jwks-url", required=True, help="the platform's public keyset URL")
    reg.add_argument("--deployment", action="append", default=[], help="a deployment id (repeat for several)")
    reg.add_argument("--name", default="", help="a name to show")
    reg.add_argument(
        "--service-origin",
        action="append",
        default=[],
        dest="service_origins",
        help="a further origin of its services (a hosted Canvas: https://school.instructure.com)",
    )
    reg.add_argument("--trust-emails", action="store_true",
                     help="a launch's email identifies the roster student of that email (only for an LMS whose "
                     "users cannot change their own email)")  # fmt: skip
    reg.add_argument("--allow-private", action="store_true",
                     help="accept URLs on loopback, link-local or private addresses (a test platform, an LMS on "
                     "the school's own network)")  # fmt: skip
    ls = sub.add_parser("list", help="the registered platforms")
    rm = sub.add_parser("remove", help="remove a platform")
    rm.add_argument("id")
    rot = sub.add_parser("rotate-key", help="a new key for the tool; the old one published for a grace period")
    rot.add_argument("--grace-hours", type=float, default=DEFAULT_GRACE_HOURS,
                     help=f"how long the old key stays in /lti/jwks (default {DEFAULT_GRACE_HOURS:g})")  # fmt: skip
    show = sub.add_parser("show-tool", help="the values to paste into the LMS")
    show.add_argument("--base", required=True, help="the tool's public address: https://tool.example.edu")
    trial.parser(sub)
    for p in (reg, ls, rm, rot):
        p.add_argument("--data-dir", type=Path, default=None, help="the server's data directory (default: ./data)")
    return ap


def data_dir(given: Path | None) -> Path:
    if given is not None:
        return given
    from server.core.settings import load_settings

    return load_settings().data_dir


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.command == "try":
        return trial.main(args)
    if args.command == "show-tool":
        if problem := url_problem(args.base):
            print(f"--base: {problem}", file=sys.stderr)
            return 1
        print(show_tool(args.base))
        return 0
    folder = data_dir(args.data_dir)
    folder.mkdir(parents=True, exist_ok=True)
    if args.command == "rotate-key":
        if not 0 <= args.grace_hours <= 24 * 90:
            print("--grace-hours: expected 0 to 2160 hours", file=sys.stderr)
            return 1
        keys = ToolKeys(folder / "lti")
        old, new, until = keys.rotate(args.grace_hours * 3600)
        print(new)
        print(f"new key {new}; the old key {old} stays in /lti/jwks until "
              f"{datetime.fromtimestamp(until, UTC):%Y-%m-%d %H:%M UTC}, then it is dropped")  # fmt: skip
        return 0
    store = LtiStore(folder)
    if args.command == "list":
        for p in store.platforms():
            print(describe(p))
        return 0
    if args.command == "remove":
        if not store.remove(args.id):
            print(f"no platform {args.id!r} (python -m server.lti list shows them)", file=sys.stderr)
            return 1
        print(f"removed {args.id}")
        return 0
    try:
        p = store.register(
            issuer=args.issuer, client_id=args.client_id, auth_url=args.auth_url, token_url=args.token_url,
            jwks_url=args.jwks_url, deployment_ids=args.deployment, name=args.name, now=time.time(),
            allow_private=args.allow_private, trust_emails=args.trust_emails, service_origins=args.service_origins,
        )  # fmt: skip
    except DomainError as e:
        for err in e.errors:
            print(f"{err['path']}: {err['message']}", file=sys.stderr)
        return 1
    print(p["id"])
    print(describe(p))
    return 0
