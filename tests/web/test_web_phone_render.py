"""Render on a phone (issue #42, Major 3): at 390 px wide the picture was about 1 900 px below the Render button,
under the Build panel, and nothing near the button moved. Now the Build panel is folded on a narrow screen, the
render's progress is said beside the button, and the picture is brought into view when the render starts.

The fixtures of tests/web/conftest.py (`python -m server` on loopback, Debian's Chromium, the `phone` page: 390 x
844 px). Screenshots go to $WEB_SHOTS (default /tmp/web_shots) as phone-render-*.png."""

from __future__ import annotations

from tests.support.axe import assert_accessible
from tests.support.page import DESKTOP, PHONE, SHOTS, set_scene, whitted

IN_VIEW = """(sel) => { const r = document.querySelector(sel).getBoundingClientRect();
    return {top: r.top, bottom: r.bottom, height: r.height,
            inView: r.height > 0 && r.top >= 0 && r.bottom <= innerHeight}; }"""


def test_render_on_a_phone_shows_the_progress_at_the_button_and_brings_the_picture_into_view(phone):
    page = phone.open().page
    assert page.evaluate("() => innerWidth") == PHONE["width"]
    assert page.evaluate("() => document.querySelector('#build-details').open") is False  # folded on a phone
    set_scene(page, whitted(80, 60, spp=64))
    page.locator("#btn-render").scroll_into_view_if_needed()
    page.evaluate("() => window.scrollBy(0, -200)")  # the button in the middle of the screen, as a thumb finds it
    button = page.evaluate(IN_VIEW, "#btn-render")
    assert button["inView"], button
    stage = page.evaluate(IN_VIEW, "#stage")
    assert not stage["inView"], f"the picture was already in view before Render: {stage}"

    page.click("#btn-render")
    # measured in the first frame with the job on the stage (one evaluation, not three): the progress where the button
    # is, both in view, and the picture's place in view. Its first image, a pass later, makes the stage taller and
    # takes it to the top of the screen (the button above it then): measured after, the button was out of view.
    start = page.wait_for_function(
        f"""() => {{
            if (!document.querySelector('#stage').dataset.job) return null;
            const inView = {IN_VIEW};
            return {{near: inView('#render-progress'), button: inView('#btn-render'), stage: inView('#stage'),
                     text: document.querySelector('#render-progress-text').textContent.trim(),
                     image: !document.querySelector('#render-img').hidden}};
        }}"""
    ).json_value()
    near, button = start["near"], start["button"]
    assert near["inView"], start
    assert button["inView"], start
    assert 0 <= near["top"] - button["bottom"] < 80, f"the progress is not beside the button: {start}"
    assert start["text"] != "", start
    assert start["stage"]["inView"], f"the picture is not in view after Render: {start}"
    phone.shot("phone-render-started")

    page.wait_for_selector("#stage[data-status=done]", timeout=120_000)
    page.wait_for_selector("#render-img:not([hidden])")
    # its last layout settles within a frame or two of the end
    page.wait_for_function(f"() => ({IN_VIEW})('#render-img').inView", timeout=5_000)
    img = page.evaluate(IN_VIEW, "#render-img")
    assert img["inView"] and img["height"] > 100, img
    assert page.text_content("#render-progress-text").startswith("done in")
    phone.shot("phone-render-done")
    assert_accessible(page, "workspace on a phone after Render")
    # "Show the picture" brings it back after scrolling away
    page.evaluate("() => window.scrollTo(0, 0)")
    page.locator("#btn-to-picture").scroll_into_view_if_needed()
    assert not page.evaluate(IN_VIEW, "#stage")["inView"]
    page.click("#btn-to-picture")
    assert page.evaluate(IN_VIEW, "#stage")["inView"]


def test_on_a_desktop_the_build_panel_stays_open_and_render_scrolls_nothing(desktop):
    """The picture is beside the editor on a wide screen: Render moves nothing, and says its progress there too."""
    page = desktop.open().page
    assert page.evaluate("() => innerWidth") == DESKTOP["width"]
    assert page.evaluate("() => document.querySelector('#build-details').open") is True
    set_scene(page, whitted(80, 60, spp=16))
    assert page.evaluate(IN_VIEW, "#stage")["inView"]
    before = page.evaluate("() => scrollY")
    page.click("#btn-render")
    page.wait_for_selector("#stage[data-status=done]", timeout=120_000)
    page.wait_for_function("() => document.querySelector('#render-progress-text').textContent.startsWith('done in')")
    assert page.evaluate("() => scrollY") == before
    assert page.evaluate(IN_VIEW, "#render-progress")["inView"]
    page.locator(".editor-actions").screenshot(path=str(SHOTS / "desktop-render-progress.png"))
