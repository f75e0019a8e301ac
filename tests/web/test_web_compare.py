"""The two ray trees at a pixel (web/js/course/compare.js, web/css/compare.css) in a real browser.

Uses the fixtures of tests/web/conftest.py (`python -m server` on loopback with one render worker and an instructor
token; Debian's Chromium through Playwright; a page that fails on console errors it did not expect). A small
assignment is published and a student submits a scene whose red ball is blue, over the API; once it is graded,
a page of the server imports compare.js, as the student's page does on a click of the difference map, and
shows the trees of a pixel on the ball, and of a pixel of the mirror floor where the ball is reflected (the
difference a ray deeper). Screenshots go to $WEB_SHOTS (compare-*.png) for a person to look at.
"""

from __future__ import annotations

import copy
import re
from datetime import UTC, datetime, timedelta

import httpx

from tests.support.api import INSTRUCTOR, bearer, wait_for
from tests.support.page import DESKTOP, TEACHER, Page

W, H = 48, 36
REFERENCE = {
    "version": 1,
    "name": "a ball on a mirror floor",
    "camera": {"lookfrom": [0, 1.5, 5], "lookat": [0, 0, 0], "vfov": 40},
    "film": {"width": W, "height": H},
    "sampler": {"type": "jittered", "spp": 1},
    "render": {"integrator": "whitted", "max_depth": 3},
    "background": [0.2, 0.3, 0.5],
    "ambient": 0.05,
    "materials": {"red": {"kd": [0.8, 0.1, 0.1], "ks": 0.3, "shininess": 40}, "floor": {"kd": 0.4, "kr": 0.5}},
    "lights": [{"type": "point", "position": [2, 4, 4], "intensity": 40}],
    "objects": [
        {"type": "plane", "name": "mirror floor", "point": [0, -0.8, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "sphere", "name": "red ball", "center": [0, 0, 0], "radius": 0.8, "material": "red"},
    ],
}
SPEC = {
    "version": 1,
    "name": "A ball on a mirror",
    "render": {"width": W, "height": H, "seed": 7, "spp": 1},
    "reference": {"scene": REFERENCE, "spp": 16, "pixels": {"points": 1}, "flip": {"points": 1}},
}
TOPS = "ss => ss.map(s => s.getBoundingClientRect().top)"
SHOW = """async ([args, css]) => {
    if (css && !document.querySelector('link[href="/css/compare.css"]')) {
        const link = Object.assign(document.createElement("link"), { rel: "stylesheet", href: "/css/compare.css" });
        const loaded = new Promise((ok) => link.addEventListener("load", ok));
        document.head.append(link);
        await loaded;
    }
    const { showCompare } = await import("/js/course/compare.js");
    let box = document.querySelector("#compare-test");
    if (!box) {
        box = Object.assign(document.createElement("div"), { id: "compare-test" });
        box.style.cssText = "padding: 12px; background: #fff";
        document.body.prepend(box);
    }
    const answer = await showCompare(box, args);
    return answer && answer.difference;
}"""
DOM = """() => {
    const root = document.querySelector("#compare-test > div.compare");
    const sides = [...root.querySelectorAll("section.compare-side")];
    return {
        message: root.querySelector(".compare-message")?.textContent,
        sides: sides.map((s) => ({
            side: s.dataset.side,
            title: s.querySelector("h3").textContent,
            boxes: s.querySelectorAll("g.rt-node").length,
            differs: [...s.querySelectorAll("g.rt-node.differs")].map((g) => Number(g.dataset.id)),
        })),
        messageAbove: sides.every((s) => root.querySelector(".compare-message").compareDocumentPosition(s) & 4),
    };
}"""
VISIBLE = """(side) => {
    const s = document.querySelector(`#compare-test section.compare-side[data-side=${side}]`);
    const g = s.querySelector("g.rt-node.differs .box").getBoundingClientRect();
    const box = s.querySelector(".compare-tree").getBoundingClientRect();
    const inBox = g.left >= box.left - 1 && g.right <= box.right + 1
        && g.top >= box.top - 1 && g.bottom <= box.bottom + 1;
    const inView = g.top >= 0 && g.bottom <= innerHeight && g.left >= 0 && g.right <= innerWidth;
    const stroke = getComputedStyle(s.querySelector("g.rt-node.differs .box")).stroke;
    return { inBox, inView, width: g.width, stroke };
}"""


def graded_submission(srv) -> dict:
    """Publish, enrol one student, submit the blue ball over the API; wait until it is graded."""
    deadline = (datetime.now(UTC) + timedelta(days=1)).isoformat()
    r = httpx.post(f"{srv.url}/api/assignments", json={"spec": SPEC, "deadline": deadline}, headers=TEACHER)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    r = httpx.post(f"{srv.url}/api/assignments/{aid}/roster", content="id,name,email\ns1,Sam,\n",
                   headers={**TEACHER, "Content-Type": "text/csv"})  # fmt: skip
    token = r.json()["students"][0]["token"]
    scene = copy.deepcopy(REFERENCE)
    scene["materials"]["red"]["kd"] = [0.1, 0.1, 0.8]
    r = httpx.post(f"{srv.url}/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(token))
    assert r.status_code == 202, r.text
    sid = r.json()["id"]

    def done():
        s = httpx.get(f"{srv.url}/api/assignments/{aid}/submissions/{sid}", headers=TEACHER).json()
        return s["status"] == "graded" and s

    wait_for(done, 240, "the submission graded", interval=0.2)
    return {"aid": aid, "sid": sid, "token": token}


def reflected_pixel(srv, sub: dict) -> tuple[int, int]:
    """A pixel of the floor below the ball whose first difference is the reflection of the ball (a ray deeper)."""
    for y in range(H // 2, H):
        r = httpx.get(f"{srv.url}/api/assignments/{sub['aid']}/submissions/{sub['sid']}/raytree",
                      params={"x": W // 2, "y": y}, headers=TEACHER, timeout=60)  # fmt: skip
        d = r.json()["difference"]
        if d and len(d["student"]) == 1 and d["what"] == "material":
            return W // 2, y
    raise AssertionError("no pixel of the floor reflects the ball")


def test_web_compare_shows_both_trees_and_marks_the_first_difference(desktop, phone, server):
    sub = graded_submission(server)
    page = desktop.open().page
    page.evaluate("(t) => localStorage.setItem('rt.token', JSON.stringify(t))", sub["token"])  # the student's link
    args = {"aid": sub["aid"], "sid": sub["sid"], "x": W // 2, "y": H // 2 - 2}
    d = page.evaluate(SHOW, [args, True])
    assert d["what"] == "material"
    assert d["student"] == []
    assert d["reference"] == []
    dom = page.evaluate(DOM)
    assert dom["message"] == d["message"]
    assert dom["message"].startswith("Where your eye ray hits red ball")
    titles = [(s["side"], s["title"]) for s in dom["sides"]]
    assert titles == [("student", "Your ray tree"), ("reference", "The reference's")]
    assert all(s["boxes"] >= 2 and s["differs"] == [0] for s in dom["sides"]), dom
    assert dom["messageAbove"]
    for side in ("student", "reference"):
        seen = page.evaluate(VISIBLE, side)
        assert seen["inBox"] and seen["inView"] and seen["stroke"] == "rgb(255, 77, 109)", seen
    # each side's colour as RGB numbers and a swatch of it (the student's ball is blue, the reference's red)
    summaries = page.eval_on_selector_all(
        "#compare-test .compare-summary", "ps => ps.map(p => [p.textContent, p.querySelector('.sw').style.background])"
    )
    assert all(re.search(r"colour RGB \(([-\d.e]+, ){2}[-\d.e]+\)$", text) for text, _ in summaries), summaries
    (_, mine), (_, theirs) = summaries
    blue, red = (tuple(map(int, re.findall(r"\d+", c))) for c in (mine, theirs))
    assert blue[2] > blue[0] and red[0] > red[2], summaries
    # side by side on a wide screen
    boxes = page.eval_on_selector_all("#compare-test section.compare-side", TOPS)
    assert boxes[0] == boxes[1]
    desktop.shot("compare-desktop")

    x, y = reflected_pixel(server, sub)
    d = page.evaluate(SHOW, [{**args, "x": x, "y": y}, False])
    assert d["what"] == "material"
    assert len(d["student"]) == 1
    dom = page.evaluate(DOM)
    assert all(s["differs"] == [d["nodes"][s["side"]]] and s["differs"] != [0] for s in dom["sides"]), (d, dom)
    assert "reflection ray (depth 2)" in dom["message"]
    for side in ("student", "reference"):
        seen = page.evaluate(VISIBLE, side)
        assert seen["inBox"] and seen["inView"], seen
    desktop.shot("compare-desktop-reflected")

    # the server's errors, in p.compare-error: a pixel outside the graded image (the browser logs the 422)
    desktop.allow.append(r"status of 422")
    page.evaluate(SHOW, [{**args, "x": W + 3}, False])
    error = page.text_content("#compare-test .compare-error")
    assert error == f"x: must be a column of the graded image in 0..{W - 1} (it is {W}x{H} pixels)"
    assert page.locator("#compare-test section.compare-side").count() == 0

    # the instructor's dashboard: `as: "instructor"`, on a phone the two trees one above the other
    p = phone.open().page
    p.evaluate("(t) => localStorage.setItem('rt.instructor', JSON.stringify(t))", INSTRUCTOR)
    d = p.evaluate(SHOW, [{**args, "x": x, "y": y, "as": "instructor"}, True])
    assert d["what"] == "material"
    tops = p.eval_on_selector_all("#compare-test section.compare-side", TOPS)
    assert tops[1] > tops[0]
    width = p.evaluate("() => document.documentElement.scrollWidth")
    assert width <= 390, f"the page is {width} px wide on a phone"
    seen = p.evaluate(VISIBLE, "student")
    assert seen["inBox"], seen
    phone.shot("compare-phone", full_page=True)


def test_web_compare_on_the_instructor_s_dashboard_in_the_instructor_s_words(browser, server):
    """/course#<aid>/<student>: a click on the difference map of a graded scene shows the two trees styled as on
    the student's page (compare.css), within the page's width at 1280, about the student ("The student's eye
    ray"), never to them ("Your")."""
    sub = graded_submission(server)
    p = Page(browser, server, DESKTOP)
    p.allow.append(r"status of 401")  # the first load, before the token is in this browser's storage
    try:
        page = p.page
        page.goto(f"{server.url}/course")
        page.evaluate("(t) => localStorage.setItem('rt.instructor', JSON.stringify(t))", INSTRUCTOR)
        page.goto(f"{server.url}/course#{sub['aid']}/s1")
        page.wait_for_function(
            """() => { const i = document.querySelector('#student-detail .grade-fig[data-picture=error_map] img');
                       return i && i.complete && i.naturalWidth > 0; }"""
        )
        img = page.locator("#student-detail .grade-fig[data-picture=error_map] img")
        img.scroll_into_view_if_needed()
        box = img.bounding_box()
        x, y = W // 2, H // 2 - 2  # on the ball: blue against red
        page.mouse.click(box["x"] + (x + 0.5) * box["width"] / W, box["y"] + (y + 0.5) * box["height"] / H)
        page.wait_for_selector("#student-detail .compare section.compare-side[data-side=reference] g.rt-node.differs")
        seen = page.evaluate(
            """() => {
                const root = document.querySelector('#student-detail .compare');
                const marked = root.querySelector('g.rt-node.differs .box');
                return {
                    titles: [...root.querySelectorAll('section.compare-side h3')].map((h) => h.textContent),
                    message: root.querySelector('.compare-message').textContent,
                    text: root.textContent,
                    overflow: getComputedStyle(root.querySelector('.compare-tree')).overflowX,
                    stroke: getComputedStyle(marked).stroke,
                    tops: [...root.querySelectorAll('section.compare-side')].map((s) => s.getBoundingClientRect().top),
                    width: document.documentElement.scrollWidth,
                };
            }"""
        )
        assert seen["titles"] == ["The student's ray tree", "The reference's"], seen
        assert seen["message"].startswith("Where the student's eye ray hits red ball"), seen["message"]
        assert "(the student's against the reference's)" in seen["message"]
        assert not re.search(r"\b[Yy]our", seen["text"]), seen["text"]
        assert seen["overflow"] == "auto" and seen["stroke"] == "rgb(255, 77, 109)", seen  # compare.css applies
        assert seen["tops"][0] == seen["tops"][1], seen  # side by side
        assert seen["width"] <= DESKTOP["width"], f"the page is {seen['width']} px wide at {DESKTOP['width']}"
        page.locator("#student-detail .compare").scroll_into_view_if_needed()
        p.shot("compare-instructor-dashboard")
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
