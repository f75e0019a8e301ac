"""The page's tests' helpers in Chromium: the browser's path and flags, the viewports, a Page (a browser context on the
page's server that fails its test on an unexpected console error), a scene set in the editor and rendered, a lesson
run; screenshots go to SHOTS ($WEB_SHOTS). The fixtures that use them are tests/web/conftest.py's."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

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


class Page:
    """A page with its console watched: `allow` lists patterns of console errors a test expects."""

    def __init__(self, browser, server, viewport):
        self.context = browser.new_context(viewport=viewport)
        self.page = self.context.new_page()
        self.page.set_default_timeout(60_000)
        self.server = server
        self.errors: list[str] = []
        self.allow: list[str] = []
        self.page.on("console", lambda m: m.type == "error" and self.errors.append(f"console: {m.text}"))
        self.page.on("pageerror", lambda e: self.errors.append(f"uncaught: {e}"))
        self.context.add_init_script(CSP_WATCH)

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
