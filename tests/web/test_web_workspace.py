"""The workspace in a real browser (the fixtures of test_web_page.py): the picture and the ray tree of a clicked
pixel in view together, Render an early Tab stop, the Example menu following the text, and the browser's
ResizeObserver notice kept out of the error banner. Screenshots go to $WEB_SHOTS (workspace-*.png)."""

from __future__ import annotations

import json

from conftest import scene_dict
from test_web_page import DESKTOP, browser, desktop, render, server, set_scene, whitted  # noqa: F401  (fixtures)

SETTLED = """() => new Promise((done) => {
    let last = -1, same = 0;
    const look = () => { same = scrollY === last ? same + 1 : 0; last = scrollY; same >= 5 ? done(scrollY) : requestAnimationFrame(look); };
    look();
})"""
BOXES = """() => Object.fromEntries(['#render-img', '#rt-diagram', '#rt-diagram .rt-node'].map((sel) => {
    const r = document.querySelector(sel).getBoundingClientRect();
    return [sel, {top: r.top, bottom: r.bottom, left: r.left, right: r.right, height: r.height}];
}))"""


def test_web_workspace_a_pixel_click_keeps_the_picture_and_its_tree_in_view(desktop):  # noqa: F811
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
