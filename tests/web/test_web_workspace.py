"""The workspace in a real browser (the fixtures of tests/web/conftest.py): the picture and the ray tree of a clicked
pixel in view together, Render an early Tab stop, the Example menu following the text, and the browser's
ResizeObserver notice kept out of the error banner. Screenshots go to $WEB_SHOTS (workspace-*.png)."""

from __future__ import annotations

import json

from tests.support.page import DESKTOP, render, set_scene, whitted
from tests.support.scene import scene_dict

SETTLED = """() => new Promise((done) => {
    let last = -1, same = 0, frames = 0;  // five frames without a move (a smooth scroll ends), at most 600
    const look = () => {
        same = scrollY === last ? same + 1 : 0;
        last = scrollY;
        same >= 5 || ++frames > 600 ? done(scrollY) : requestAnimationFrame(look);
    };
    look();
})"""
BOXES = """() => Object.fromEntries(['#render-img', '#rt-diagram', '#rt-diagram .rt-node'].map((sel) => {
    const r = document.querySelector(sel).getBoundingClientRect();
    return [sel, {top: r.top, bottom: r.bottom, left: r.left, right: r.right, height: r.height}];
}))"""


def test_web_workspace_a_pixel_click_keeps_the_picture_and_its_tree_in_view(desktop):
    page = desktop.open().page
    set_scene(page, whitted(160, 120, spp=4))
    render(page)
    img = page.locator("#render-img")
    img.scroll_into_view_if_needed()
    box = img.bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.69, box["y"] + box["height"] * 0.58)  # the glass ball
    page.wait_for_selector("#rt-diagram .rt-node")
    page.evaluate(SETTLED)
    desktop.shot("workspace-pixel-click")
    desktop.shot("workspace-pixel-click-full", full_page=True)
    boxes = page.evaluate(BOXES)
    h = DESKTOP["height"]
    picture, tree, root = boxes["#render-img"], boxes["#rt-diagram"], boxes["#rt-diagram .rt-node"]
    assert picture["top"] >= 0 and picture["bottom"] <= h, boxes  # the whole picture
    assert 0 <= tree["top"] and root["bottom"] <= h and min(tree["bottom"], h) - tree["top"] >= 150, boxes
    width = page.evaluate("() => document.documentElement.scrollWidth")
    assert width <= DESKTOP["width"], f"the page is {width} px wide at {DESKTOP['width']} px"


def test_web_workspace_render_is_the_tab_stop_after_the_scene_text(desktop):
    """From the top of the page Tab reaches the scene text, and the next Tab is Render (it was the 49th stop,
    after every field of the form)."""
    page = desktop.open().page
    reached = []
    for _ in range(30):
        page.keyboard.press("Tab")
        reached.append(page.evaluate("() => document.activeElement.id || document.activeElement.tagName"))
        if reached[-1] == "btn-render":
            break
    assert reached[-1] == "btn-render", reached
    assert len(reached) <= 15 and reached[-2] == "scene-text", reached
    outline = page.evaluate("() => getComputedStyle(document.activeElement).outlineStyle")
    assert outline != "none"
    page.keyboard.press("Enter")  # the focused Render renders the editor's scene
    page.wait_for_function("() => document.querySelector('#stage').dataset.job", timeout=60_000)


def menu(page) -> str:
    return page.input_value("#example-select")


def test_web_workspace_the_example_menu_follows_the_text(desktop):
    page = desktop.open().page
    page.wait_for_selector("#validation-status[data-kind=ok]")
    assert menu(page) == "whitted"
    whitted_text = page.input_value("#scene-text")
    page.fill("#scene-text", whitted_text.replace('"vfov": 40', '"vfov": 41', 1))  # an edit of the example
    assert menu(page) == "whitted"
    cornell = scene_dict("cornell")
    page.fill("#scene-text", json.dumps(cornell, indent=2))  # other text pasted over it
    page.wait_for_function("() => document.querySelector('#example-select').value === ''")
    page.reload()  # the editor keeps the text; the menu does not name the example it came from
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert json.loads(page.input_value("#scene-text"))["name"] == cornell["name"] and menu(page) == ""
    page.select_option("#example-select", "whitted")
    page.wait_for_function("() => JSON.parse(document.querySelector('#scene-text').value).name.startsWith('Whitted')")
    assert menu(page) == "whitted"
    page.fill("#scene-text", "{ not a scene")  # typed text that is no scene
    page.wait_for_function("() => document.querySelector('#example-select').value === ''")


RESIZE_LOOP = """() => new Promise((done) => {
    let seen = false;
    window.addEventListener("error", (e) => { if (/ResizeObserver loop/.test(e.message)) seen = true; });
    const box = Object.assign(document.createElement("div"), { id: "ro-loop" });
    document.body.append(box);
    let n = 0;
    const ro = new ResizeObserver(() => { if (n++ < 4) box.style.height = `${10 + n}px`; });  // resizes what it watches
    ro.observe(box);
    setTimeout(() => { ro.disconnect(); box.remove(); done(seen); }, 300);
})"""


def test_web_workspace_the_resize_observer_notice_is_no_error(desktop):
    """The browser's "ResizeObserver loop completed with undelivered notifications" (a notice: the rest is
    delivered in the next frame) leaves the banner hidden; a real error still shows it."""
    desktop.allow += [r"ResizeObserver loop", r"a real error"]
    page = desktop.open().page
    assert page.evaluate(RESIZE_LOOP), "the browser raised no ResizeObserver notice: the test proves nothing"
    page.wait_for_timeout(100)
    assert page.is_hidden("#banner"), page.inner_text("#banner")
    page.evaluate("() => setTimeout(() => { throw new Error('a real error'); })")
    page.wait_for_selector("#banner:not([hidden])")
    assert "a real error" in page.inner_text("#banner")
