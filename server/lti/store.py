"""The LTI tables, in the data directory's database (DATA/jobs.sqlite3) beside the jobs and the course.

- `lti_platforms`: one per registered platform (an LMS and the client id it gave this tool): its issuer, the
  URLs of its OIDC auth request, access tokens and JWKS, the further origins its services may be at
  (`service_origins`: a hosted Canvas's school address), and whether its emails identify people
  (`trust_emails`). A short hex `id` names it in the command and the API.
- `lti_deployments`: the deployment ids a platform's launches may carry (one per place the tool is installed).
- `lti_logins`: logins in flight: the OIDC `state` and `nonce` the tool made at /lti/login (256 random bits
  each), taken once by the launch that comes back with them, and only within `max_age` seconds; kept
  LOGIN_KEEP (10 minutes) at most, MAX_LOGINS_PER_ADDRESS per client address and MAX_LOGINS in all.
- `lti_origins`: the web origins a platform's verified launches named as their return URLs (a hosted Canvas
  shows its courses at the school's own address, which its registration does not name): they may frame the
  tool's pages too (at most MAX_ORIGINS per platform).
- `lti_nonces`: the nonces of verified launches, so that an id_token is accepted once (kept until an hour
  past its expiry, then pruned).

Every write is one statement or one transaction (server/core/db.py); each thread has its own connection.
"""

from __future__ import annotations

import ipaddress
import re
import secrets
import sqlite3
from pathlib import Path
from typing import TypedDict, cast
from urllib.parse import urlsplit

from server.core.db import Tables
from server.core.errors import Invalid

SCHEMA = """
CREATE TABLE IF NOT EXISTS lti_platforms (
    id TEXT PRIMARY KEY,                  -- 12 hex digits
    issuer TEXT NOT NULL,                 -- the id_token's `iss` (Canvas: https://canvas.instructure.com)
    client_id TEXT NOT NULL,              -- the id_token's `aud`: this tool at that platform
    name TEXT NOT NULL DEFAULT '',
    auth_url TEXT NOT NULL,               -- the OIDC authentication request's endpoint
    token_url TEXT NOT NULL,              -- OAuth 2 access tokens (client credentials) for the services
    jwks_url TEXT NOT NULL,               -- the platform's public keys
    created_at REAL NOT NULL,             -- Unix time (s)
    trust_emails INTEGER NOT NULL DEFAULT 0,  -- 1: a launch's email identifies a roster student (--trust-emails)
    service_origins TEXT NOT NULL DEFAULT '', -- further origins of its services, space-separated
    UNIQUE (issuer, client_id)
);
CREATE TABLE IF NOT EXISTS lti_deployments (
    platform_id TEXT NOT NULL,
    deployment_id TEXT NOT NULL,
    PRIMARY KEY (platform_id, deployment_id)
);
CREATE TABLE IF NOT EXISTS lti_logins (
    state TEXT PRIMARY KEY,               -- 256 random bits (base64url): the OIDC `state`
    nonce TEXT NOT NULL,                  -- 256 random bits: the id_token must carry it
    platform_id TEXT NOT NULL,
    target_link_uri TEXT NOT NULL,
    created_at REAL NOT NULL,
    storage_target TEXT,                  -- LTI Platform Storage's frame, when the platform offered it
    address TEXT NOT NULL DEFAULT ''      -- the client address of the login (server/core/clients.py's key)
);
CREATE TABLE IF NOT EXISTS lti_origins (
    platform_id TEXT NOT NULL,
    origin TEXT NOT NULL,                 -- scheme://host[:port] a verified launch named as its return URL's
    seen_at REAL NOT NULL,
    PRIMARY KEY (platform_id, origin)
);
CREATE TABLE IF NOT EXISTS lti_nonces (
    platform_id TEXT NOT NULL,
    nonce TEXT NOT NULL,
    exp REAL NOT NULL,                    -- the id_token's expiry: the row is pruned an hour after it
    PRIMARY KEY (platform_id, nonce)
);
"""


class PlatformRow(TypedDict):
    """A registered platform as LtiStore.platform, .find, .platforms and .register return it: its row of
    `lti_platforms` (`trust_emails` as a bool) with its deployment ids (`lti_deployments`, in the order added):
    what the launch, the services and the course's LMS side read as `platform`."""

    id: str  # 12 hex digits
    issuer: str
    client_id: str
    name: str
    auth_url: str
    token_url: str
    jwks_url: str
    created_at: float
    trust_emails: bool
    service_origins: str  # space-separated origins
    deployment_ids: list[str]


class LoginRow(TypedDict):
    """A row of `lti_logins`: a login in flight, as LtiStore.take_login returns it (the launch's `state_row`)."""

    state: str
    nonce: str
    platform_id: str
    target_link_uri: str
    created_at: float
    storage_target: str | None
    address: str


URL_FIELDS = ("issuer", "auth_url", "token_url", "jwks_url")
HOST = re.compile(r"[a-z0-9_-]+(?:\.[a-z0-9_-]+)*\.?|[0-9a-f:.]+")  # a DNS name, IPv4, or IPv6 (unbracketed)
MAX_TEXT = 2048  # characters of a URL, client id, deployment id or name
LOGIN_KEEP = 600  # seconds: logins never taken are pruned after this (a launch takes its login within it)
MAX_LOGINS_PER_ADDRESS = 100  # logins in flight from one client address (a school behind one address)
MAX_LOGINS = 5000  # logins in flight in all
NONCE_KEEP = 3600  # seconds past a nonce's token's expiry that it is kept
MAX_ORIGINS = 20  # origins learned from one platform's launches
MAX_SERVICE_ORIGINS = 20  # further service origins of one platform
PRIVATE_WORDS = (
    "a loopback, link-local or private address (give allow_private, --allow-private, for a test platform or an "
    "LMS on the school's own network)"
)


class TooManyLogins(Exception):
    """A login refused: too many in flight from its address, or in all (`retry_after`: seconds)."""

    def __init__(self, message: str, retry_after: int):
        super().__init__(message)
        self.message, self.retry_after = message, retry_after


def loopback_host(host: str) -> bool:
    name = host.strip("[]").lower().rstrip(".")
    if name == "localhost" or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def private_host(host: str) -> bool:
    """A host name that is loopback (localhost), or an IP address that is loopback, link-local, private,
    unspecified or reserved: nothing a platform on the internet is at (a name is not resolved here)."""
    name = host.strip("[]").lower().rstrip(".")
    if loopback_host(name):
        return True
    try:
        ip = ipaddress.ip_address(name)
    except ValueError:
        return False
    ip = ip.ipv4_mapped or ip if isinstance(ip, ipaddress.IPv6Address) else ip
    return ip.is_loopback or ip.is_link_local or ip.is_private or ip.is_unspecified or ip.is_reserved


def url_problem(value: object, allow_private: bool = True) -> str | None:
    """Why `value` is no URL a platform may have (None: it is one): https, or http on a loopback host only; a
    loopback, link-local or private host only with `allow_private`."""
    if not isinstance(value, str) or not value:
        return "expected a URL (https://...)"
    if len(value) > MAX_TEXT or any(c.isspace() for c in value):
        return f"expected a URL of at most {MAX_TEXT} characters without spaces"
    try:
        parts = urlsplit(value)
        host = parts.hostname or ""
        parts.port  # noqa: B018 (raises ValueError for a port that is not one)
    except ValueError:
        return f"expected a URL; got {value[:100]!r}"
    if not HOST.fullmatch(host):
        return f"expected a URL with a host name; got {value[:100]!r}"
    if parts.scheme not in ("https", "http") or (parts.scheme == "http" and not loopback_host(host)):
        return f"expected an https:// URL (http:// only on 127.0.0.1, localhost or [::1]); got {value[:100]!r}"
    if not allow_private and private_host(host):
        return f"{value[:100]!r} is on {PRIVATE_WORDS}"
    return None


def url_origin(url: str) -> str | None:
    """scheme://host[:port] of a URL (lower case, the default port left out); None when it has none."""
    try:
        parts = urlsplit(url)
        host, port = parts.hostname, parts.port
    except (ValueError, AttributeError):
        return None
    if parts.scheme not in ("https", "http") or not host:
        return None
    host = f"[{host}]" if ":" in host else host
    default = {"https": 443, "http": 80}[parts.scheme]
    return f"{parts.scheme}://{host}" + (f":{port}" if port and port != default else "")


def platform_origins(platform: PlatformRow) -> list[str]:
    """The origins a platform's services and pages may be at: those of its registered URLs, and its further
    service origins (a hosted Canvas at the school's address)."""
    urls = [platform[f] for f in URL_FIELDS] + (platform.get("service_origins") or "").split()
    return sorted({o for u in urls if (o := url_origin(u))})


def on_platform(platform: PlatformRow, url: object) -> bool:
    """Whether `url` is an http(s) URL at one of the platform's origins (its access token may go there)."""
    return isinstance(url, str) and url_origin(url) in platform_origins(platform)


def text_problem(value: object, what: str) -> str | None:
    if not isinstance(value, str) or not value.strip():
        return f"expected {what}: a non-empty text"
    if len(value) > MAX_TEXT:
        return f"expected {what} of at most {MAX_TEXT} characters"
    return None


def check_platform(values: dict, allow_private: bool = False) -> None:
    """Invalid (422) naming every field of a platform's registration that is wrong (a loopback, link-local or
    private address among them, unless `allow_private`)."""
    errors = [{"path": f, "message": m} for f in URL_FIELDS if (m := url_problem(values.get(f), allow_private))]
    origins = values.get("service_origins", [])
    if not isinstance(origins, list) or len(origins) > MAX_SERVICE_ORIGINS:
        errors.append({"path": "service_origins", "message": f"expected a list of at most {MAX_SERVICE_ORIGINS} "
                       "origins (https://school.example.edu)"})  # fmt: skip
    else:
        for i, o in enumerate(origins):
            m = url_problem(o, allow_private)
            if m is None and url_origin(o) != o.rstrip("/").lower():
                m = f"expected an origin, scheme://host[:port] with no path; got {o[:100]!r}"
            if m:
                errors.append({"path": f"service_origins[{i}]", "message": m})
    if m := text_problem(values.get("client_id"), "the client id the platform gave this tool"):
        errors.append({"path": "client_id", "message": m})
    deployments = values.get("deployment_ids")
    if not isinstance(deployments, list):
        errors.append({"path": "deployment_ids", "message": "expected a list of deployment ids"})
    else:
        for i, d in enumerate(deployments):
            if m := text_problem(d, "a deployment id"):
                errors.append({"path": f"deployment_ids[{i}]", "message": m})
    name = values.get("name", "")
    if not isinstance(name, str) or len(name) > MAX_TEXT:
        errors.append({"path": "name", "message": f"expected a text of at most {MAX_TEXT} characters"})
    if errors:
        raise Invalid(errors)


class LtiStore(Tables):
    def __init__(self, data_dir: Path):
        super().__init__(data_dir, SCHEMA)

    # -- platforms -------------------------------------------------------------------------------

    def register(
        self, issuer: str, client_id: str, auth_url: str, token_url: str, jwks_url: str,
        deployment_ids: list[str], name: str = "", now: float = 0.0, *, allow_private: bool = False,
        trust_emails: bool = False, service_origins: list[str] | None = None,
    ) -> PlatformRow:  # fmt: skip
        """The platform of (issuer, client_id), made or updated: its URLs, name, further service origins and
        whether its emails identify people, and its deployment ids replaced by `deployment_ids` (Invalid, 422,
        naming the field of a wrong value; a loopback, link-local or private address is one unless
        `allow_private`)."""
        origins = list(service_origins or [])
        values = dict(issuer=issuer, client_id=client_id, auth_url=auth_url, token_url=token_url, jwks_url=jwks_url)
        check_platform({**values, "deployment_ids": deployment_ids, "name": name, "service_origins": origins},
                       allow_private)  # fmt: skip
        extra_origins: set[str] = {origin for o in origins if (origin := url_origin(o)) is not None}  # (all: checked)
        extra = " ".join(sorted(extra_origins))
        with self._tx() as db:
            row = db.execute(
                "SELECT id FROM lti_platforms WHERE issuer = ? AND client_id = ?", (issuer, client_id)
            ).fetchone()
            pid = row["id"] if row else secrets.token_hex(6)
            if row:
                db.execute(
                    "UPDATE lti_platforms SET auth_url = ?, token_url = ?, jwks_url = ?, name = ?, trust_emails = ?,"
                    " service_origins = ? WHERE id = ?",
                    (auth_url, token_url, jwks_url, name, int(trust_emails), extra, pid),
                )
            else:
                db.execute(
                    "INSERT INTO lti_platforms (id, issuer, client_id, name, auth_url, token_url, jwks_url, created_at,"
                    " trust_emails, service_origins) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (pid, issuer, client_id, name, auth_url, token_url, jwks_url, now, int(trust_emails), extra),
                )
            db.execute("DELETE FROM lti_deployments WHERE platform_id = ?", (pid,))
            db.executemany(
                "INSERT OR IGNORE INTO lti_deployments (platform_id, deployment_id) VALUES (?, ?)",
                [(pid, d) for d in deployment_ids],
            )
        made = self.platform(pid)
        assert made is not None  # written just above
        return made

    def add_deployment(self, platform_id: str, deployment_id: str) -> PlatformRow | None:
        """The platform with one more deployment id (None: no such platform)."""
        if m := text_problem(deployment_id, "a deployment id"):
            raise Invalid([{"path": "deployment_id", "message": m}])
        with self._tx() as db:
            if db.execute("SELECT 1 FROM lti_platforms WHERE id = ?", (platform_id,)).fetchone() is None:
                return None
            db.execute(
                "INSERT OR IGNORE INTO lti_deployments (platform_id, deployment_id) VALUES (?, ?)",
                (platform_id, deployment_id),
            )
        return self.platform(platform_id)

    def platform(self, platform_id: str) -> PlatformRow | None:
        row = self.db.execute("SELECT * FROM lti_platforms WHERE id = ?", (platform_id,)).fetchone()
        return self._with_deployments(row) if row else None

    def find(self, issuer: str, client_id: str | None = None) -> PlatformRow | None:
        """The platform of `issuer` and `client_id`; without a client id, the only one of that issuer (None when
        there are none or several)."""
        if client_id is not None:
            sql, args = "SELECT * FROM lti_platforms WHERE issuer = ? AND client_id = ?", (issuer, client_id)
        else:
            sql, args = "SELECT * FROM lti_platforms WHERE issuer = ? LIMIT 2", (issuer,)
        rows = self.db.execute(sql, args).fetchall()
        return self._with_deployments(rows[0]) if len(rows) == 1 else None

    def platforms(self) -> list[PlatformRow]:
        rows = self.db.execute("SELECT * FROM lti_platforms ORDER BY created_at, id").fetchall()
        return [self._with_deployments(r) for r in rows]

    def remove(self, platform_id: str) -> bool:
        with self._tx() as db:
            gone = db.execute("DELETE FROM lti_platforms WHERE id = ?", (platform_id,)).rowcount
            for table in ("lti_deployments", "lti_logins", "lti_nonces", "lti_origins"):
                db.execute(f"DELETE FROM {table} WHERE platform_id = ?", (platform_id,))
        return bool(gone)

    def _with_deployments(self, row: sqlite3.Row) -> PlatformRow:
        out = dict(row)
        out["trust_emails"] = bool(out.get("trust_emails"))
        rows = self.db.execute(
            "SELECT deployment_id FROM lti_deployments WHERE platform_id = ? ORDER BY rowid", (out["id"],)
        ).fetchall()
        out["deployment_ids"] = [r["deployment_id"] for r in rows]
        return cast(PlatformRow, out)

    # -- logins in flight --------------------------------------------------------------------------

    def new_login(
        self, platform_id: str, target_link_uri: str, now: float, storage_target: str | None = None,
        address: str = "",
    ) -> tuple[str, str]:  # fmt: skip
        """A fresh (state, nonce) for a login to `platform_id` from client `address`, kept with its time (those
        older than LOGIN_KEEP pruned), and the platform's storage frame when it offered LTI Platform Storage (the
        launch then checks the state there). TooManyLogins past MAX_LOGINS_PER_ADDRESS in flight from the
        address, or MAX_LOGINS in all."""
        state, nonce = secrets.token_urlsafe(32), secrets.token_urlsafe(32)
        with self._tx() as db:
            db.execute("DELETE FROM lti_logins WHERE created_at < ?", (now - LOGIN_KEEP,))
            mine = db.execute("SELECT COUNT(*), MIN(created_at) FROM lti_logins WHERE address = ?", (address,))
            mine, oldest = mine.fetchone()
            if mine >= MAX_LOGINS_PER_ADDRESS:
                raise TooManyLogins(
                    f"{mine} sign-ins from this address are under way, the most it may have "
                    f"({MAX_LOGINS_PER_ADDRESS}): finish one, or open the link again in a few minutes",
                    max(1, int(oldest + LOGIN_KEEP - now) + 1),
                )  # fmt: skip
            everyone, oldest = db.execute("SELECT COUNT(*), MIN(created_at) FROM lti_logins").fetchone()
            if everyone >= MAX_LOGINS:
                raise TooManyLogins(
                    f"{everyone} sign-ins are under way, the most this server keeps ({MAX_LOGINS}): open the link "
                    "again in a few minutes",
                    max(1, int(oldest + LOGIN_KEEP - now) + 1),
                )  # fmt: skip
            db.execute(
                "INSERT INTO lti_logins (state, nonce, platform_id, target_link_uri, created_at, storage_target,"
                " address) VALUES (?, ?, ?, ?, ?, ?, ?)",
                (state, nonce, platform_id, target_link_uri[:MAX_TEXT], now, storage_target, address),
            )
        return state, nonce

    def take_login(self, state: str, now: float, max_age: float = LOGIN_KEEP) -> LoginRow | None:
        """The login of `state`, deleted (a state is used once); None if unknown, used or older than `max_age` s."""
        with self._tx() as db:
            row = db.execute("SELECT * FROM lti_logins WHERE state = ?", (state,)).fetchone()
            if row is None:
                return None
            db.execute("DELETE FROM lti_logins WHERE state = ?", (state,))
        return cast(LoginRow, dict(row)) if now - row["created_at"] <= max_age else None

    # -- nonces seen -------------------------------------------------------------------------------

    def use_nonce(self, platform_id: str, nonce: str, exp: float, now: float) -> bool:
        """True the first time a platform's `nonce` is used; False after (a replay). Rows of tokens that expired
        more than NONCE_KEEP s ago are pruned."""
        with self._tx() as db:
            db.execute("DELETE FROM lti_nonces WHERE exp < ?", (now - NONCE_KEEP,))
            added = db.execute(
                "INSERT OR IGNORE INTO lti_nonces (platform_id, nonce, exp) VALUES (?, ?, ?)",
                (platform_id, nonce, exp),
            ).rowcount
        return added == 1

    # -- origins seen in launches --------------------------------------------------------------------

    def add_origin(self, platform_id: str, origin: str, now: float) -> bool:
        """Keep an origin a verified launch of `platform_id` named; True when it is new (and was kept: at most
        MAX_ORIGINS per platform)."""
        with self._tx() as db:
            if db.execute(
                "SELECT 1 FROM lti_origins WHERE platform_id = ? AND origin = ?", (platform_id, origin)
            ).fetchone():
                return False
            count = db.execute("SELECT COUNT(*) FROM lti_origins WHERE platform_id = ?", (platform_id,)).fetchone()[0]
            if count >= MAX_ORIGINS:
                return False
            db.execute(
                "INSERT INTO lti_origins (platform_id, origin, seen_at) VALUES (?, ?, ?)", (platform_id, origin, now)
            )
        return True

    def origins_seen(self) -> list[str]:
        rows = self.db.execute("SELECT DISTINCT origin FROM lti_origins ORDER BY origin").fetchall()
        return [r["origin"] for r in rows]
