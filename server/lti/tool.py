"""The LTI tool as the app holds it (`app.state.lti`): its keys, its tables, the platforms' key sets, the
service client, the launch handler, its clock, and the origins that may frame the tool's pages
(server/core/security.py's `frame_ancestors`): those of the registered platforms' issuers and auth URLs, and
those their verified launches named as return URLs."""

from __future__ import annotations

import re
import secrets
import threading
import time
from collections.abc import Callable
from pathlib import Path
from urllib.parse import urlsplit

from server.lti.handler import EchoHandler, LaunchHandler
from server.lti.keys import ToolKeys
from server.lti.launch import LTI, JwksCache, Launch
from server.lti.services import ServiceClient
from server.lti.store import LtiStore

ORIGIN = re.compile(r"https?://(?:[a-z0-9._-]+|\[[0-9a-f:.]+\])(?::[0-9]{1,5})?")
HOLD_SECONDS, MAX_HELD = 120.0, 10000  # a launch waits this long for its storage check; at most this many wait
ORIGINS_TTL = 60.0  # seconds: platforms registered by the command line (another process) are seen this late


def origin(url: str) -> str | None:
    """scheme://host[:port] of `url`, or None when it is no plain web origin (nothing a CSP could misread)."""
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        return None
    host = parts.hostname or ""
    host = f"[{host}]" if ":" in host else host
    text = f"{parts.scheme}://{host}" + (f":{port}" if port else "")
    return text if ORIGIN.fullmatch(text) else None


class LtiTool:
    def __init__(self, data_dir: Path, clock: Callable[[], float] = time.time):
        self.keys = ToolKeys(Path(data_dir) / "lti")
        self.store = LtiStore(data_dir)
        self.jwks = JwksCache()
        self.services = ServiceClient(self.keys)
        self.handler: LaunchHandler = EchoHandler()
        self.clock = clock  # Unix time: logins' ages, tokens' times
        self._origins: tuple[float, list[str]] | None = None
        self._lock = threading.Lock()
        self._held: dict[str, tuple[float, Launch]] = {}  # launches waiting for the platform storage's check

    def origins(self) -> list[str]:
        """The origins of the registered platforms' issuers, auth URLs and further service origins, and those
        their launches named (cached; `refresh` after a change)."""
        with self._lock:
            if self._origins is not None and time.monotonic() - self._origins[0] < ORIGINS_TTL:
                return self._origins[1]
        found = {o for o in self.store.origins_seen() if ORIGIN.fullmatch(o)}
        for p in self.store.platforms():
            found |= {o for o in (origin(p["issuer"]), origin(p["auth_url"])) if o}
            found |= {o for o in (p.get("service_origins") or "").split() if ORIGIN.fullmatch(o)}  # a school's address
        with self._lock:
            self._origins = (time.monotonic(), sorted(found))
        return self._origins[1]

    def learn_origins(self, launch: Launch) -> None:
        """The origins of a verified launch's return URLs (launch_presentation's, deep linking's), kept so that
        the platform's pages at that address may frame the tool (a hosted Canvas at the school's own domain)."""
        urls = [(launch.claims.get(LTI + "launch_presentation") or {}).get("return_url")]
        urls.append((launch.deep_linking or {}).get("deep_link_return_url"))
        found = {o for u in urls if isinstance(u, str) and (o := origin(u))}
        added = [o for o in sorted(found) if self.store.add_origin(launch.platform["id"], o, self.clock())]
        if added:
            self.refresh()

    def close(self) -> None:
        self.services.http.close()

    def hold(self, launch: Launch) -> str:
        """Keep a checked launch for a moment (HOLD_SECONDS) while its page checks the state in the platform's
        storage; the one-time id that opens it (`take`)."""
        key = secrets.token_urlsafe(24)
        now = time.monotonic()
        with self._lock:
            for k in [k for k, (t, _) in self._held.items() if t < now]:
                del self._held[k]
            if len(self._held) >= MAX_HELD:
                self._held.pop(next(iter(self._held)))
            self._held[key] = (now + HOLD_SECONDS, launch)
        return key

    def take(self, key: str) -> Launch | None:
        """The launch held under `key`, once (None if unknown, taken or too old)."""
        with self._lock:
            held = self._held.pop(key, None)
        return held[1] if held is not None and held[0] >= time.monotonic() else None

    def refresh(self) -> None:
        with self._lock:
            self._origins = None
