"""The page's pictures and addresses in a real browser (the fixtures of tests/web/conftest.py): the magnifier and
the full-size view of a lesson's panels, the examples' previews ready without clicking, links to a scene and
to a job (read-only), the address following tabs and lessons with Back and Forward, the whole description,
the ray-tree diagram fitted to its panel. Each test fails on any console error or CSP violation it does not
expect."""

from __future__ import annotations

import json
import random
import re
import string

import pytest

from tests.support.api import Server, run_solutions
from tests.support.page import DESKTOP, Page, render, set_scene, whitted
from tests.support.scene import scene_dict

LESSON_DONE = """(n) => document.querySelectorAll('.lesson-panel').length === n
    && [...document.querySelectorAll('.lesson-panel')]
        .every(p => ['done', 'refused', 'failed'].includes(p.dataset.status))
    && [...document.querySelectorAll('.lesson-image img')].every(i => i.complete && i.naturalWidth > 0)"""


def banner_says(page, words: str) -> None:
    page.wait_for_function("(w) => document.querySelector('#banner').innerText.includes(w)", arg=words)


def lenses(page) -> list[dict]:
    return page.evaluate(
        """() => [...document.querySelectorAll('.lesson-image')].map(box => {
            const lens = box.querySelector('.inspect-lens');
            return lens ? {hidden: lens.hidden, pixel: lens.dataset.pixel, data: lens.toDataURL()} : null;
        })"""
    )


def test_web_inspect_magnifier_follows_on_every_panel_and_full_size_view(desktop):
    page = desktop.open("#lessons/bounces").page  # the address opens the lesson
    page.wait_for_function(LESSON_DONE, arg=3, timeout=90_000)
    assert page.get_attribute("#lesson-stage", "data-lesson") == "bounces"
    imgs = page.locator(".lesson-image img")
    box = imgs.nth(0).bounding_box()
    # hovering the first picture at about 3/10, 6/10 of it: the same picture pixel magnified on all three
    page.mouse.move(box["x"] + 0.305 * box["width"], box["y"] + 0.605 * box["height"])
    shown = lenses(page)
    assert [ln["hidden"] for ln in shown] == [False] * 3
    assert {ln["pixel"] for ln in shown} == {"48,72"}
    assert shown[0]["data"] != shown[2]["data"]  # each lens shows its own picture (1 bounce vs 3)
    desktop.shot("inspect-lenses")
    # nearest neighbour: the lens is made of 8 x 8 squares of one colour each
    same = page.evaluate(
        """() => {
            const c = document.querySelector('.lesson-image .inspect-lens');
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let same = 0, all = 0;
            for (let y = 0; y < c.height; y += 8) for (let x = 0; x < c.width; x += 8) {
                const i = 4 * (y * c.width + x), j = 4 * ((y + 6) * c.width + x + 6);
                if (y + 6 < c.height && x + 6 < c.width) { all++; if (d[i] === d[j] && d[i+1] === d[j+1]) same++; }
            }
            return same / all;
        }"""
    )
    assert same > 0.9
    # moving over the third picture moves every lens; leaving hides them
    box3 = imgs.nth(2).bounding_box()
    page.mouse.move(box3["x"] + 0.505 * box3["width"], box3["y"] + 0.255 * box3["height"])
    assert {ln["pixel"] for ln in lenses(page)} == {"80,30"}
    page.mouse.move(5, 5)
    assert [ln["hidden"] for ln in lenses(page)] == [True] * 3
    # the keyboard: focus a picture, arrows move the lenses one pixel (Shift: 10)
    imgs.nth(1).focus()
    page.keyboard.press("ArrowRight")
    assert {ln["pixel"] for ln in lenses(page)} == {"81,60"}
    page.keyboard.press("Shift+ArrowDown")
    assert {ln["pixel"] for ln in lenses(page)} == {"81,70"}
    page.keyboard.press("Escape")
    assert [ln["hidden"] for ln in lenses(page)] == [True] * 3
    # Enter (or a click) opens the group at full size, x4 first, pixelated; the zoom goes to x8; Esc closes
    page.keyboard.press("Enter")
    page.wait_for_selector("dialog.inspect-dialog[open]")
    full = page.locator("dialog .inspect-full-img")
    assert full.count() == 3
    assert (
        page.evaluate("() => getComputedStyle(document.querySelector('.inspect-full-img')).imageRendering")
        == "pixelated"
    )
    assert full.nth(0).bounding_box()["width"] == pytest.approx(640, abs=1)
    page.eval_on_selector(".inspect-zoom", "el => { el.value = '3'; el.dispatchEvent(new Event('input')); }")
    assert full.nth(2).bounding_box()["width"] == pytest.approx(1280, abs=1)
    assert page.inner_text(".inspect-zoom-out") == "×8"
    page.eval_on_selector(
        ".inspect-scroll >> nth=0", "el => { el.scrollLeft = 300; el.dispatchEvent(new Event('scroll')); }"
    )
    page.wait_for_function("() => document.querySelectorAll('.inspect-scroll')[2].scrollLeft === 300")
    desktop.shot("inspect-full")
    page.keyboard.press("Escape")
    page.wait_for_selector("dialog.inspect-dialog", state="detached")
    assert page.evaluate("() => document.activeElement === document.querySelectorAll('.lesson-image img')[1]")
    imgs.nth(0).click()
    page.wait_for_selector("dialog.inspect-dialog[open]")
    page.click("dialog .inspect-head button")
    page.wait_for_selector("dialog.inspect-dialog", state="detached")


def test_web_inspect_address_follows_tabs_and_lessons_back_and_forward(desktop):
    page = desktop.open().page
    page.click("#tab-lessons")
    assert page.evaluate("location.hash") == "#lessons"
    page.click(".lesson-button[data-lesson=dof]")
    assert page.evaluate("location.hash") == "#lessons/dof"
    page.wait_for_function(LESSON_DONE, arg=2, timeout=90_000)
    page.click(".lesson-button[data-lesson=motion]")
    assert page.evaluate("location.hash") == "#lessons/motion"
    page.wait_for_function("() => document.querySelector('#lesson-stage').dataset.lesson === 'motion'")
    page.click("#tab-examples")
    assert page.evaluate("location.hash") == "#examples" and page.is_visible("#page-examples")
    page.go_back()
    page.wait_for_function("() => !document.querySelector('#page-lessons').hidden")
    assert page.get_attribute("#lesson-stage", "data-lesson") == "motion"
    page.go_back()
    page.wait_for_function("() => document.querySelector('#lesson-stage').dataset.lesson === 'dof'")
    page.go_back()
    page.go_back()
    page.wait_for_function("() => !document.querySelector('#page-work').hidden")
    assert page.evaluate("location.hash") == ""
    page.go_forward()
    page.wait_for_function("() => !document.querySelector('#page-lessons').hidden")
    # the lessons tab comes back to the lesson it showed
    page.click("#tab-work")
    page.click("#tab-lessons")
    assert page.evaluate("location.hash") == "#lessons/dof"
    # an unknown lesson says so, plainly
    page.goto(f"{desktop.server.url}/#lessons/glossy-nope")
    banner_says(page, "There is no lesson 'glossy-nope'")


def test_web_inspect_whole_description_and_the_tree_fitted(desktop):
    page = desktop.open().page
    text = page.inner_text("#scene-description")
    assert text == scene_dict("whitted")["description"]  # the editor starts with whitted
    assert page.evaluate(
        "() => { const d = document.querySelector('#scene-description'); return d.scrollHeight <= d.clientHeight + 1 }"
    )
    set_scene(page, whitted(160, 120, spp=4))
    render(page)
    page.wait_for_selector("#render-img:not([hidden])")
    box = page.locator("#render-img").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 125 / 160, box["y"] + box["height"] * 70 / 120)  # the glass ball
    page.wait_for_selector("#rt-diagram svg")
    assert page.get_attribute("#rt-fit", "aria-pressed") == "true"
    fit = page.evaluate(
        """() => { const c = document.querySelector('#rt-diagram'), s = c.querySelector('svg');
            return {w: +s.getAttribute('width'), h: +s.getAttribute('height'), cw: c.clientWidth,
                    ch: parseFloat(getComputedStyle(c).maxHeight), sw: c.scrollWidth, scale: +c.dataset.scale} }"""
    )
    assert fit["w"] <= fit["cw"]
    assert fit["h"] <= fit["ch"]
    assert fit["sw"] <= fit["cw"]
    page.click("#rt-fit")  # off: the boxes at their own size
    assert page.evaluate("() => +document.querySelector('#rt-diagram svg').getAttribute('width')") >= fit["w"]


def test_web_inspect_links_open_a_scene_in_the_editor(desktop, browser):
    page = desktop.open().page
    scene = whitted(96, 72)
    scene["name"] = "Zoë's linked scene"
    set_scene(page, scene)
    page.click("#btn-share-scene")
    link = page.input_value("#load-note input.share-link")
    assert "#scene/" in link
    assert len(link) < 2000
    other = Page(browser, desktop.server, DESKTOP)  # another student, another browser
    try:
        other.page.goto(link)
        other.page.wait_for_selector("body[data-ready=true]", state="attached")
        assert json.loads(other.page.input_value("#scene-text")) == scene
        assert other.page.evaluate("location.hash") == ""  # the editor holds it from here
        assert other.unexpected_errors() == []
    finally:
        other.context.close()
    # a broken link says so; a scene too large for a link says to save it as a file
    page.goto(f"{desktop.server.url}/#scene/AAAA$$")
    banner_says(page, "This link does not hold a scene the editor can open (the link has characters")
    page.click("#banner button.close")
    page.goto(link[: link.index("#scene/") + 40])  # cut short
    banner_says(page, "cut short or damaged")
    page.click("#banner button.close")
    page.goto(link[: link.index("#scene/") + 47])  # cut short at a length base64 may have
    banner_says(page, "cut short or damaged")
    big = whitted(96, 72)
    big["description"] = "".join(random.Random(1).choices(string.ascii_letters, k=60_000))
    set_scene(page, big)
    page.click("#btn-share-scene")
    page.wait_for_function("() => document.querySelector('#load-note').innerText.includes('too large for a link')")
    assert "Save file" in page.inner_text("#load-note")


def test_web_inspect_read_only_link_to_a_job(desktop, browser):
    page = desktop.open().page
    set_scene(page, whitted(96, 72, spp=4))
    render(page)
    job_id = page.get_attribute("#stage", "data-job")
    page.click("#btn-share")
    link = page.input_value("#share-note input.share-link")
    assert f"#shared/{job_id}/share-" in link
    guest = Page(browser, desktop.server, DESKTOP)  # someone else follows the link: image and ray trees, read-only
    try:
        guest.page.goto(link)
        guest.page.wait_for_selector("body[data-ready=true]", state="attached")
        g = guest.page
        g.wait_for_function(
            "() => { const i = document.querySelector('#render-img'); return !i.hidden && i.naturalWidth === 96 }"
        )
        assert g.get_attribute("#stage", "data-shared") == "true"
        assert g.is_disabled("#btn-cancel")
        assert g.is_disabled("#btn-share")
        assert "read-only" in g.inner_text("#share-note")
        box = g.locator("#render-img").bounding_box()
        g.mouse.click(box["x"] + box["width"] * 0.7, box["y"] + box["height"] * 0.6)
        g.wait_for_selector("#rt-diagram svg")
        assert g.evaluate("() => localStorage.getItem('rt.viewer.job')") is None  # not kept as the guest's job
        # the same job without the token, or with another token, is not found
        guest.allow.append("404")
        for bad in (f"#shared/{job_id}/", f"#shared/{job_id}/share-AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA"):
            g.goto(f"{desktop.server.url}/{bad}")
            g.wait_for_selector("body[data-ready=true]", state="attached")
            g.reload()
            g.wait_for_selector("body[data-ready=true]", state="attached")
            words = g.inner_text("#banner") + g.inner_text("#viewer-message")
            assert "cut short" in words or "no such job" in words, words
            assert g.get_attribute("#stage", "data-job") != job_id
        assert guest.unexpected_errors() == []
    finally:
        guest.context.close()


@pytest.fixture(scope="module")
def fresh_server(tmp_path_factory):
    """A server that renders the examples' previews ahead, as `python -m server` does; at 64 pixels, not the
    default 160 (what the page is asked here is the cards' states and pictures, whatever their size: 16 % of the
    pixels, about 7 s of CPU against 45; tests/server/jobs/test_previews.py renders them at the default size), the
    radiosity examples' solutions from the run's shared cache (`run_solutions`) where another server solved them."""
    env = {"TRACER_PREVIEWS_AHEAD": "1", "TRACER_PREVIEW_SIZE": "64", **run_solutions(tmp_path_factory)}
    with Server(tmp_path_factory.mktemp("web-previews"), workers=1, env=env) as s:
        yield s


def test_web_inspect_previews_ready_without_opening_them(browser, fresh_server):
    p = Page(browser, fresh_server, DESKTOP)
    try:
        page = p.open("#examples").page
        cards = page.locator("#gallery .card")
        n = cards.count()
        assert n > 10
        first = [c.get_attribute("data-preview") for c in cards.all()]
        assert set(first) <= {"queued", "rendering", "ready"}  # a state from the start, never a black box
        assert page.locator("#gallery .card:not([data-preview=ready]) img:visible").count() == 0
        page.wait_for_function(
            """() => [...document.querySelectorAll('#gallery .card')].every(c => c.dataset.preview === 'ready'
                && c.querySelector('img').complete && c.querySelector('img').naturalWidth > 0)""",
            timeout=240_000,
        )
        p.shot("examples-ready", full_page=True)
        assert p.unexpected_errors() == []
    finally:
        p.context.close()


def test_web_inspect_shadow_rays_grouped_and_the_view_starts_at_the_eye_ray(desktop):
    """16 light samples: a hit's 16 shadow rays to a light are one box ("16 shadow rays to light 0", "11 reach the
    light, 5 blocked"; before, 48 boxes side by side under the floor's hit, unreadable even fitted), opened with a
    click and folded back; unfitted, the view starts at the eye ray's box (issue #42)."""
    page = desktop.open().page
    scene = scene_dict("soft_shadows")
    scene["film"] = {"width": 160, "height": 120}
    scene["sampler"] = {"type": "jittered", "spp": 1}
    set_scene(page, scene)
    render(page)
    page.wait_for_selector("#render-img:not([hidden])")
    box = page.locator("#render-img").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 80.5 / 160, box["y"] + box["height"] * 108.5 / 120)  # the floor
    page.wait_for_selector("#rt-diagram svg .rt-group")
    diagram = page.locator("#rt-diagram")
    nodes, boxes = int(diagram.get_attribute("data-nodes")), int(diagram.get_attribute("data-boxes"))
    groups = page.locator("#rt-diagram .rt-group")
    assert groups.count() >= 3 and nodes >= 49 and boxes <= nodes - 3 * 15, (groups.count(), nodes, boxes)
    texts = page.eval_on_selector_all(
        "#rt-diagram .rt-group",
        "gs => gs.map(g => [...g.querySelectorAll('text')].map(t => t.textContent).join('\\n'))",
    )
    for text in texts:
        m = re.search(r"16 shadow rays to light (\d)\s+(\d+) reach(?:es)? the light, (\d+) blocked", text)
        assert m and int(m[2]) + int(m[3]) == 16, text
    assert float(diagram.get_attribute("data-scale")) >= 0.5  # fitted, its words still readable
    diagram.scroll_into_view_if_needed()
    desktop.shot("raytree-grouped")
    page.click("#rt-fit")  # off: the boxes at their own size, the eye ray's box in view

    def in_view(selector: str) -> bool:
        return page.evaluate(
            """(s) => { const c = document.querySelector('#rt-diagram').getBoundingClientRect();
                        const b = document.querySelector(s).getBoundingClientRect();
                        return b.left >= c.left && b.right <= c.right && b.top >= c.top && b.bottom <= c.bottom; }""",
            selector,
        )

    assert in_view("#rt-diagram .rt-node[data-id='0']")
    first = groups.first.get_attribute("data-group")
    groups.first.click()  # opened: its 16 rays, each a box, and a tab to fold them
    page.wait_for_function("(n) => +document.querySelector('#rt-diagram').dataset.boxes === n", arg=boxes + 15)
    fold = page.locator(f"#rt-diagram .rt-fold[data-group='{first}']")
    assert fold.text_content() == "▴ fold the 16 shadow rays"
    desktop.shot("raytree-group-opened")
    fold.click()
    page.wait_for_function("(n) => +document.querySelector('#rt-diagram').dataset.boxes === n", arg=boxes)
    assert page.locator(f"#rt-diagram .rt-group[data-group='{first}']").count() == 1
