"""The page's tests' helpers in Chromium: the browser's path and flags, the viewports, a Page (a browser context on the
page's server that fails its test on an unexpected console error), a scene set in the editor and rendered, a lesson
run; screenshots go to SHOTS ($WEB_SHOTS). The fixtures that use them are tests/web/conftest.py's."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from urllib.parse import urlsplit

from tests.support.api import INSTRUCTOR, bearer
from tests.support.scene import scene_dict, small

CHROMIUM = "/usr/bin/chromium"


CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


SHOTS = Path(os.environ.get("WEB_SHOTS", "/tmp/web_shots"))


DESKTOP = {"width": 1280, "height": 800}


PHONE = {"width": 390, "height": 844}


DONE = ("done", "failed", "cancelled")


TEACHER = bearer(INSTRUCTOR)


CSP_WATCH = """document.addEventListener("securitypolicyviolation", (e) =>
    console.error(`content security policy: ${e.violatedDirective} blocked ${e.blockedURI || "inline"}`));"""


class _Lease:
    """One browser context with its one page, lent to a test by Page and given back by its `close()`: cleaned (the
    page back at about:blank, the storage and cookies of every origin it visited cleared, the listeners, routes and
    viewport a test gave it taken away) and kept for the next test of the same browser and options. A fresh
    context's first page cost 1.9 s of CPU, a page lent again 0.7 s (Chromium's new renderer, then the page's 44
    files fetched and compiled again), over the suite's hundreds of pages. A context a test changed in a way that
    cannot be taken back (an init script, a context route, permissions, a closed page) is closed for good instead.
    What is seen is what goes through `Page.context`: the page's own init scripts, exposed functions, extra headers
    and media emulation are not (no test uses them; a test that does should close the real context itself)."""

    free: dict[tuple, list[_Lease]] = {}
    TAINTING = frozenset(
        {"add_init_script", "route", "route_from_har", "route_web_socket", "grant_permissions", "add_cookies",
         "set_extra_http_headers", "set_offline", "set_geolocation", "expose_binding", "expose_function", "clock",
         "tracing", "set_http_credentials"}
    )  # fmt: skip

    def __init__(self, browser, options: dict):
        self.key = self._key(browser, options)
        self.options = options
        self.context = browser.new_context(**options)
        self.context.add_init_script(CSP_WATCH)
        self.page = self.context.new_page()
        self.origins: set[str] = set()
        self.page.on("framenavigated", lambda f: self.origins.add(_origin(f.url)))
        self.listeners = self._listeners()  # those of its own: any other is a test's
        self.tainted = False

    @staticmethod
    def _key(browser, options: dict) -> tuple:
        return id(browser), json.dumps(options, sort_keys=True)

    @classmethod
    def take(cls, browser, options: dict) -> _Lease:
        free = cls.free.get(cls._key(browser, options), [])
        while free:
            lease = free.pop()
            if not lease.page.is_closed():
                lease.tainted = False
                return lease
        return cls(browser, options)

    def _listeners(self) -> dict[str, list]:
        events = self.page._impl_obj._events  # Playwright's emitter: a listener or a list of them per event
        return {e: list(v) if isinstance(v, list) else [v] for e, v in events.items()}

    def give_back(self) -> None:
        if self.tainted or self.page.is_closed():
            self.context.close()
            return
        try:
            for other in self.context.pages:
                if other is not self.page:
                    self.origins.add(_origin(other.url))
                    other.close()
            impl = self.page._impl_obj
            for event, listeners in self._listeners().items():
                for listener in listeners:
                    if listener not in self.listeners.get(event, []):
                        impl.remove_listener(event, listener)
            self.page.unroute_all(behavior="ignoreErrors")
            if self.page.viewport_size != self.options.get("viewport"):
                self.page.set_viewport_size(self.options["viewport"])
            self.origins.add(_origin(self.page.url))
            self.page.goto("about:blank")
            cdp = self.context.new_cdp_session(self.page)
            for origin in self.origins - {"null"}:
                cdp.send("Storage.clearDataForOrigin", {"origin": origin, "storageTypes": "all"})
            cdp.detach()
            self.origins.clear()
            self.context.clear_cookies()
            self.page.set_default_timeout(60_000)
            self.page.set_default_navigation_timeout(60_000)
        except Exception:  # a page that cannot be cleaned is not lent again
            self.context.close()
            raise
        _Lease.free.setdefault(self.key, []).append(self)


def _origin(url: str) -> str:
    parts = urlsplit(url)
    return f"{parts.scheme}://{parts.netloc}" if parts.scheme in ("http", "https") else "null"


class _LentContext:
    """What a test sees as `Page.context`: the lent context; `close()` gives it back (_Lease), and a call that would
    change it for later tests (TAINTING) has it closed for good instead."""

    def __init__(self, lease: _Lease, on_close):
        self._lease, self._on_close = lease, on_close

    def __getattr__(self, name: str):
        if name in _Lease.TAINTING:
            self._lease.tainted = True
        return getattr(self._lease.context, name)

    def close(self) -> None:
        self._on_close()


class Page:
    """A page with its console watched: `allow` lists patterns of console errors a test expects. Its context and page
    are lent (_Lease): no cookies, storage, listeners or routes of one test reach the next; `context.close()` gives
    them back. `options`: the context's own (a time zone, downloads), beside the viewport."""

    def __init__(self, browser, server, viewport, **options):
        self._lease = _Lease.take(browser, {"viewport": viewport, **options})
        self._closed = False
        self.context = _LentContext(self._lease, self._give_back)
        self.page = self._lease.page
        self.page.set_default_timeout(60_000)
        self.server = server
        self.errors: list[str] = []
        self.allow: list[str] = []
        self.page.on("console", lambda m: m.type == "error" and self.errors.append(self.console_error(m)))
        self.page.on("pageerror", lambda e: self.errors.append(f"uncaught: {e}"))

    def console_error(self, message) -> str:
        """How a console error is listed in `errors`."""
        return f"console: {message.text}"

    def _give_back(self) -> None:
        if not self._closed:
            self._closed = True
            self._lease.give_back()

    def open(self, hash_: str = "") -> Page:
        self.page.goto(f"{self.server.url}/{hash_}")
        self.page.wait_for_selector("body[data-ready=true]", state="attached")
        return self

    def shot(self, name: str, full_page: bool = False) -> None:
        self.page.screenshot(path=str(SHOTS / f"{name}.png"), full_page=full_page)

    def unexpected_errors(self) -> list[str]:
        return [e for e in self.errors if not any(re.search(a, e) for a in self.allow)]


def set_scene(page, scene: dict) -> None:
    """Replace the editor's text with a scene and wait for the server's verdict."""
    page.fill("#scene-text", json.dumps(scene, indent=2))
    page.wait_for_function("() => document.querySelector('#validation-status').dataset.kind !== 'busy'")


def editor_text(page) -> str:
    return page.input_value("#scene-text")


def render(page, timeout: float = 60_000) -> None:
    """Render and wait for this job to end: the stage's job must be a new one first (right after the click the
    stage still shows the previous job's "done", and a busy machine answers the submit later)."""
    before = page.get_attribute("#stage", "data-job")
    page.click("#btn-render")
    page.wait_for_function(
        "([before, done]) => { const s = document.querySelector('#stage').dataset;"
        " return s.job && s.job !== before && done.includes(s.status); }",
        arg=[before, list(DONE)],
        timeout=timeout,
    )


def run_lesson(page, lesson: str, panels: int) -> list[str]:
    """Click a lesson and wait for each of its panels to end; their statuses."""
    page.click(f".lesson-button[data-lesson={lesson}]")
    page.wait_for_function(
        f"""() => document.querySelector('#lesson-stage').dataset.lesson === '{lesson}'
            && document.querySelectorAll('.lesson-panel').length === {panels}
            && [...document.querySelectorAll('.lesson-panel')]
                .every(p => ['done', 'refused', 'failed'].includes(p.dataset.status))""",
        timeout=90_000,
    )
    return [p.get_attribute("data-status") for p in page.locator(".lesson-panel").all()]


def whitted(width=160, height=120, spp=4, **render_) -> dict:
    return small(scene_dict("whitted"), width, height, sampler={"type": "jittered", "spp": spp}, render=render_ or {})


def radiosity_scene(size: int = 64) -> dict:
    """The two-pass Cornell box at a few pixels, with big patches and few form-factor rays: it solves
    (a few hundred shots) and renders in about a second."""
    radiosity = {"patch_size": 0.5, "rays": 1024, "display": "two-pass"}
    sampler = {"type": "jittered", "spp": 1}
    return small(scene_dict("cornell_radiosity"), size, size, sampler=sampler, render={"radiosity": radiosity})
