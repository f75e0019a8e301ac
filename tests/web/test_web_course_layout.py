"""/course's layout once the admin has made a course and added staff (issue #42): the TA's link used to run on
unbroken, widen the Courses panel and squeeze the Add-staff inputs to slivers over the Assignments column. At
1280, 1024 and 390 px no element sticks out of its panel sideways, the page never scrolls sideways, the forms'
inputs keep a usable width, and every link on the page wraps and has a Copy button that copies it (axe-core
finds no serious violation). The new-course id's `pattern` is a regular expression Chromium accepts (it logged
one it could not compile, and checked nothing): the page's console stays free of errors. Screenshots:
$WEB_SHOTS/course-layout-*.png.
"""

from __future__ import annotations

from tests.support.axe import assert_accessible
from tests.support.course_page import open_course
from tests.support.page import SHOTS

WIDTHS = (1280, 1024, 390)
MIN_INPUT = 120  # px: a field one can read and type in

OVERFLOW = """() => {
    const out = [];
    const html = document.documentElement;
    if (html.scrollWidth > html.clientWidth + 1)
        out.push(`the page scrolls sideways: ${html.scrollWidth} > ${html.clientWidth}`);
    for (const panel of document.querySelectorAll('main .panel')) {
        const box = panel.getBoundingClientRect();
        if (box.right > html.clientWidth + 1)
            out.push(`#${panel.id || panel.className} ends at ${box.right} past the window`);
        for (const el of panel.querySelectorAll('*')) {
            const r = el.getBoundingClientRect();
            if (!r.width || getComputedStyle(el).visibility === 'hidden') continue;
            if (r.right > box.right + 1 || r.left < box.left - 1)
                out.push(`${el.tagName.toLowerCase()}#${el.id}.${el.className} [${r.left}, ${r.right}] outside ` +
                         `${panel.id || panel.className} [${box.left}, ${box.right}]`);
        }
    }
    return out;
}"""

INPUTS = """() => [...document.querySelectorAll('.staff-form input, .staff-form select')]
    .map(el => [el.id, el.getBoundingClientRect().width])"""


def test_web_course_layout_holds_after_add_staff_and_its_link_wraps_with_copy(browser, server, tmp_path):
    p = open_course(browser, server, tmp_path)
    page = p.page
    p.context.grant_permissions(["clipboard-read", "clipboard-write"], origin=server.url)
    page.wait_for_selector("#course-form")
    assert page.evaluate("() => { new RegExp(document.querySelector('#new-course-id').pattern, 'v'); return true; }")
    page.fill("#new-course-id", "layout-101_b")  # the pattern is checked as it is typed
    assert page.evaluate("() => document.querySelector('#new-course-id').validity.valid")
    page.fill("#new-course-name", "Rendering for the long-winded")
    page.click("#course-form button[type=submit]")
    page.wait_for_selector("#course-list li[data-id=layout-101_b]")
    page.fill("#new-course-id", "-no")
    assert page.evaluate("() => document.querySelector('#new-course-id').validity.patternMismatch")
    page.fill("#new-course-id", "")

    page.select_option("#staff-course", "layout-101_b")
    page.fill("#staff-id", "ta-with-a-rather-long-identifier")
    page.fill("#staff-name", "Tamsin Alexandra Longname-Fitzgerald")
    page.select_option("#staff-role", "ta")
    page.click("#staff-form button[type=submit]")
    page.wait_for_selector("#staff-link")
    link = page.text_content("#staff-link")
    assert link.startswith(f"{server.url}/course#token="), link

    for width in WIDTHS:
        page.set_viewport_size({"width": width, "height": 900})
        page.wait_for_timeout(50)  # a frame for the layout
        page.screenshot(path=str(SHOTS / f"course-layout-{width}.png"), full_page=True)
        assert page.evaluate(OVERFLOW) == [], width
        narrow = [(i, w) for i, w in page.evaluate(INPUTS) if w < MIN_INPUT]
        assert narrow == [], (width, narrow)
        # every link on the page wraps, with its Copy button beside it
        links = page.evaluate(
            """() => [...document.querySelectorAll('main code, main .course-link')].map(el => {
                const box = el.closest('.course-link');
                const text = box ? box.querySelector('code') : el;
                return {text: el.textContent.slice(0, 40), wrap: getComputedStyle(text).overflowWrap,
                        copy: !!box?.querySelector('button.copy')};
            })"""
        )
        assert links and all(x["wrap"] == "anywhere" and x["copy"] for x in links), links
        lines = page.evaluate("() => document.querySelector('#staff-link').getClientRects().length")
        assert lines >= (2 if width == 390 else 1), (width, lines)  # a token is one word: at 390 px it wraps

    assert_accessible(page, "the courses panel with a new TA's link")  # (at 390 px)
    page.click("#staff-status button.copy")
    page.wait_for_function("() => document.querySelector('#staff-status button.copy').textContent === 'Copied'")
    assert page.evaluate("() => navigator.clipboard.readText()") == link
    p.context.close()
    assert p.unexpected_errors() == []
