"""A student's own tracer explained on the page (web/js/course/owntracer.js, treecompare.js; issue #38) in a real
browser: the student's assignment page and the instructor's /course.

test_web_page's server (`python -m server` on loopback, one render worker, an instructor token) and Debian's
Chromium through Playwright. An assignment is published through the API with a small reference (32 x 24) and
three probe pixels of its own (the mirror ball, the red ball, the floor); the student's image is the reference
scene rendered by the service's own workspace route, handed in on the page as an image from their tracer. The
feedback lists the probes; the student pastes a tree log made of the reference's own centre-ray trees (traced
by POST /api/raytree, as the grader traces them) with the eye ray of one tree through its pixel's corner, half a
pixel off: the page shows the two trees of each pixel side by side, in the diagram, over each image and in 3D,
with the first difference (`eye_ray`) said and marked. A log with errors shows each at its JSON path. The
instructor opens the student on /course: the same comparison, in their words, and the dashboard's bar chart of
first differences counts it. Screenshots go to $WEB_SHOTS (own-tracer-*.png); axe checks the new views.
"""

from __future__ import annotations

import copy
import json
import math
import re
from collections import Counter
from datetime import UTC, datetime, timedelta

import httpx

from tests.support.api import INSTRUCTOR, bearer, wait_for
from tests.support.axe import assert_accessible
from tests.support.own_trees import REFERENCE, H, W  # the scene of the service's tests: a mirror ball and a red ball
from tests.support.page import DESKTOP, SHOTS, TEACHER, Page

PROBES = [{"x": 12, "y": 12, "why": "the mirror ball"}, {"x": 24, "y": 14, "why": "the red ball"},
          {"x": 3, "y": 20, "why": "the floor"}]  # fmt: skip
SPEC = {
    "version": 1,
    "name": "Your own tracer",
    "render": {"width": W, "height": H, "seed": 7, "spp": 1},
    "reference": {"scene": REFERENCE, "spp": 64, "flip": {"points": 1}, "probes": PROBES},
}
SHIFTED = 1  # the tree (of PROBES) whose eye ray goes through its pixel's corner
NOT_FOUND_OR_BAD = r"status of (404|422)"


def publish(srv) -> dict:
    deadline = (datetime.now(UTC) + timedelta(days=1)).isoformat()
    body = {"spec": SPEC, "deadline": deadline, "show_reference": True}
    r = httpx.post(f"{srv.url}/api/assignments", json=body, headers=TEACHER, timeout=60)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    ready = lambda: httpx.get(f"{srv.url}/api/assignments/{aid}/reference.png", headers=TEACHER, timeout=30)  # noqa: E731
    wait_for(lambda: ready().status_code == 200, 120, "the reference rendered", interval=0.2)
    r = httpx.post(f"{srv.url}/api/assignments/{aid}/roster", content="id,name,email\ns1,Sam Own,\n",
                   headers={**TEACHER, "Content-Type": "text/csv"}, timeout=30)  # fmt: skip
    assert r.status_code == 200, r.text
    return {"aid": aid, **r.json()["students"][0]}


def students_image(srv, token: str, path) -> None:
    """The reference scene rendered as a right tracer renders it (64 jittered samples), saved as a PNG."""
    scene = dict(REFERENCE, sampler={"type": "jittered", "spp": 64})
    r = httpx.post(f"{srv.url}/api/jobs", json={"scene": scene}, headers=bearer(token), timeout=30)
    job = r.json()["id"]
    status = lambda: httpx.get(f"{srv.url}/api/jobs/{job}", headers=bearer(token), timeout=30).json()["status"]  # noqa: E731
    wait_for(lambda: status() == "done", 120, "the student's render", interval=0.2)
    path.write_bytes(httpx.get(f"{srv.url}/api/jobs/{job}/image?format=png", headers=bearer(token), timeout=30).content)


def compared(page, srv, sid: str) -> None:
    """Wait for the comparison of the log sent to be drawn, or for the page to say why not: a failure names what
    the page said and what the server's checking processes and queue were doing (CI once waited 120 s here)."""
    try:
        page.wait_for_function(
            """(id) => document.querySelector(`#${id}-result .tl-body[data-drawn=true]`)
                || document.querySelector(`#${id}-status`).dataset.kind === 'error'""",
            arg=f"tl-{sid}",
            timeout=120_000,
        )
    except Exception as exc:
        health = httpx.get(f"{srv.url}/api/health", timeout=30).text
        said = page.text_content(f"#tl-{sid}-status")
        raise AssertionError(f"no comparison drawn; the page says {said!r}; /api/health: {health}") from exc
    said = page.text_content(f"#tl-{sid}-status")
    assert page.locator(f"#tl-{sid}-result .tl-body[data-drawn=true]").count() == 1, f"the page says {said!r}"


def tree_log(srv) -> dict:
    """The reference's centre-ray trees at the probes (POST /api/raytree on the scene as the grader traces them)
    with only the log's fields, the eye ray of tree SHIFTED through its pixel's top-left corner."""
    from tracer.grading.explain import centre_scene
    from tracer.grading.treelog import as_logged

    trees = []
    for p in PROBES:
        r = httpx.post(f"{srv.url}/api/raytree", json={"scene": centre_scene(REFERENCE), "x": p["x"], "y": p["y"],
                       "sample": 0}, headers=TEACHER, timeout=120)  # fmt: skip
        assert r.status_code == 200, r.text
        trees.append(as_logged(r.json()))
    cam = REFERENCE["camera"]
    sub = lambda a, b: [x - y for x, y in zip(a, b, strict=True)]  # noqa: E731
    unit = lambda v: [x / math.sqrt(sum(c * c for c in v)) for x in v]  # noqa: E731
    cross = lambda a, b: [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]  # noqa: E731
    forward = unit(sub(cam["lookat"], cam["lookfrom"]))
    right = unit(cross(forward, [0, 1, 0]))
    up = cross(right, forward)
    half = math.tan(math.radians(cam["vfov"]) / 2)
    x, y = PROBES[SHIFTED]["x"], PROBES[SHIFTED]["y"]
    a, c = (2 * x / W - 1) * half * W / H, (1 - 2 * y / H) * half
    trees[SHIFTED]["nodes"][0]["direction"] = [f + a * r + c * u for f, r, u in zip(forward, right, up, strict=True)]
    return {"trees": trees}


SIDES = """(root) => {
    const box = document.querySelector(root);
    const body = box.querySelector('.tl-body');
    return {
        verdict: box.querySelector('.tl-verdict').textContent,
        buttons: [...box.querySelectorAll('.tl-pixel-button')].map((b) => ({
            text: b.textContent, pressed: b.getAttribute('aria-pressed'), what: b.dataset.what })),
        at: [Number(body.dataset.x), Number(body.dataset.y)],
        title: body.querySelector('.compare-title').textContent,
        message: body.querySelector('.compare-message').textContent,
        what: body.querySelector('.compare-message').dataset.what,
        sides: [...body.querySelectorAll('section.compare-side')].map((s) => ({
            side: s.dataset.side,
            title: s.querySelector('h4').textContent,
            boxes: s.querySelectorAll('g.rt-node').length,
            differs: [...s.querySelectorAll('g.rt-node.differs')].map((g) => Number(g.dataset.id)),
            depths: [...s.querySelectorAll('g.rt-node')].map((g) => Number(g.dataset.depth)),
            named: s.querySelector('g.rt-node[data-id="0"] text.strong')?.textContent,
            overlay: Number(s.querySelector('.tl-views canvas[role=img]')?.dataset.rays || 0),
            lines3d: Number(s.querySelectorAll('.tl-views canvas')[1]?.dataset.lines || 0),
            words: s.querySelector('.rt-list [data-id="0"] > .rt-li-text')?.textContent,
        })),
        text: body.textContent,
        top: [...body.querySelectorAll('section.compare-side')].map((s) => s.getBoundingClientRect().top),
        width: document.documentElement.scrollWidth,
    };
}"""


def test_web_own_tracer_probes_a_tree_log_and_the_instructor_s_view(browser, server, tmp_path):
    who = publish(server)
    aid = who["aid"]
    students_image(server, who["token"], tmp_path / "mine.png")
    log = tree_log(server)

    me = Page(browser, server, DESKTOP)
    me.allow.append(NOT_FOUND_OR_BAD)  # the bad log's 422, said on the page
    try:
        page = me.page
        # the reference image not ready at the first load (404): said, and shown once the brief is read again
        first = []
        page.route(
            f"**/api/assignments/{aid}/reference.png",
            lambda route: (
                route.fulfill(status=404, body="{}") if not first.append(1) and len(first) == 1 else route.continue_()
            ),
        )
        page.goto(who["link"])
        page.wait_for_function("() => document.querySelector('#a-reference-fig').textContent.includes('not ready yet')")
        page.wait_for_selector("body[data-ready=true]", state="attached")
        page.check("#a-kind-image")
        page.set_input_files("#a-image", str(tmp_path / "mine.png"))
        page.wait_for_function("() => document.querySelector('#a-image-note').textContent.includes('PNG')")
        page.click("#a-submit")
        page.wait_for_selector("#a-sub-list li.a-sub")
        sid = page.get_attribute("#a-sub-list li.a-sub", "data-id")
        page.wait_for_function("() => document.querySelector('#a-reference')?.naturalWidth > 0")  # the brief again
        assert "not ready yet" not in page.text_content("#a-reference-fig")
        page.wait_for_selector(f"#tl-{sid}-probes li", timeout=120_000)  # graded: its probes listed

        # the probes: the spec's own, each with why, and as a list to paste into a tracer
        shown = page.eval_on_selector_all(
            f"#tl-{sid}-probes li", "ls => ls.map(l => [l.dataset.x, l.dataset.y, l.textContent])"
        )
        assert [(int(x), int(y)) for x, y, _ in shown[:3]] == [(p["x"], p["y"]) for p in PROBES], shown
        assert shown[0][2] == "(12, 12) the mirror ball", shown
        assert page.text_content(f"#tl-{sid} .tl-pixel-list") == "[[12, 12], [24, 14], [3, 20]]"
        assert page.get_attribute(f"label[for=tl-{sid}-log]", "for") == f"tl-{sid}-log"

        # a log with one wrong node: the verdict, the differing pixel chosen, both trees with the eye ray marked
        page.fill(f"#tl-{sid}-log", json.dumps(log, indent=1))
        page.click(f"#tl-{sid}-send")
        compared(page, server, sid)
        seen = page.evaluate(SIDES, f"#tl-{sid}-result")
        x, y = PROBES[SHIFTED]["x"], PROBES[SHIFTED]["y"]
        assert seen["verdict"] == "3 trees compared: 1 differs from the reference's (first differences: eye ray).", seen
        assert [b["pressed"] for b in seen["buttons"]] == ["false", "true", "false"], seen["buttons"]
        assert [b["what"] for b in seen["buttons"]] == ["none", "eye_ray", "none"], seen["buttons"]
        texts = [b["text"] for b in seen["buttons"]]
        assert texts == ["✓(12, 12) matches", "✗(24, 14): eye ray", "✓(3, 20) matches"], texts  # ✓ ✗ aria-hidden
        assert seen["at"] == [x, y] and seen["title"] == f"Ray trees at pixel ({x}, {y}) · the red ball", seen
        assert seen["what"] == "eye_ray"
        assert "corner" in seen["message"]
        assert "(x + 0.5, y + 0.5)" in seen["message"]
        mine, ref = seen["sides"]
        assert (mine["side"], mine["title"], ref["side"], ref["title"]) == (
            "student", "Your tree (from your log)", "reference", "The reference's tree")  # fmt: skip
        assert mine["differs"] == [0] and ref["differs"] == [0], seen["sides"]
        assert mine["boxes"] == ref["boxes"] >= 2 and mine["depths"] == ref["depths"], seen["sides"]  # depth derived
        assert mine["named"].startswith("red ball · red") and ref["named"].startswith("red ball · red"), seen
        assert "hit red ball (material red)" in mine["words"]
        assert "The first difference: eye ray." in mine["words"]
        assert mine["overlay"] >= 2 and ref["overlay"] >= 2, seen["sides"]  # the rays over each image
        assert mine["lines3d"] > 0 and ref["lines3d"] > 0, seen["sides"]  # the scene in 3D
        assert seen["top"][0] == seen["top"][1], seen["top"]  # side by side
        assert not re.search(r"\b(null|undefined|NaN)\b", seen["text"]), seen["text"]  # the log's missing fields
        assert seen["width"] <= DESKTOP["width"], f"the page is {seen['width']} px wide at 1280"
        page.locator(f"#tl-{sid}").scroll_into_view_if_needed()
        page.screenshot(path=str(SHOTS / "own-tracer-student.png"), full_page=True)
        page.locator(f"#tl-{sid}-result .compare-sides").screenshot(path=str(SHOTS / "own-tracer-sides.png"))
        assert_accessible(page, "own tracer, the student's comparison", f"#tl-{sid}")

        # another pixel, from the keyboard: it matches
        page.focus(f"#tl-{sid}-result .tl-pixel-button[data-i='0']")
        page.keyboard.press("Enter")
        page.wait_for_function(f"() => document.querySelector('#tl-{sid}-result .tl-body').dataset.x === '12'")
        page.wait_for_selector(f"#tl-{sid}-result .tl-body[data-drawn=true]")
        again = page.evaluate(SIDES, f"#tl-{sid}-result")
        assert again["what"] == "none" and "matches the reference's" in again["message"], again
        assert all(s["differs"] == [] for s in again["sides"]), again["sides"]

        # on a phone: the two trees one above the other, within the page's width
        page.set_viewport_size({"width": 390, "height": 844})
        page.wait_for_function("() => document.documentElement.scrollWidth <= 390")
        narrow = page.evaluate(SIDES, f"#tl-{sid}-result")
        assert narrow["top"][1] > narrow["top"][0], narrow["top"]
        page.locator(f"#tl-{sid}-result").screenshot(path=str(SHOTS / "own-tracer-phone.png"))
        page.set_viewport_size(DESKTOP)

        # a bad log: nothing compared, every error at its path
        bad = copy.deepcopy(log)
        bad["trees"][0]["nodes"][0]["kind"] = "camera"
        bad["trees"][1]["pixel"] = [W, 0]
        page.fill(f"#tl-{sid}-log", json.dumps(bad))
        page.click(f"#tl-{sid}-send")
        page.wait_for_selector(f"#tl-{sid}-errors li[data-path]")
        paths = page.eval_on_selector_all(
            f"#tl-{sid}-errors li[data-path]", "ls => ls.map(l => [l.dataset.path, l.textContent])"
        )
        assert {"trees[0].nodes[0].kind", "trees[1].pixel"} <= {p for p, _ in paths}, paths
        assert any(p == "trees[1].pixel" and f"x in 0..{W - 1}" in t for p, t in paths), paths
        assert page.text_content(f"#tl-{sid}-status").startswith(
            f"The log has {len(paths)} errors: nothing was compared"
        )
        page.locator(f"#tl-{sid}-errors").scroll_into_view_if_needed()
        page.screenshot(path=str(SHOTS / "own-tracer-bad-log.png"))
    finally:
        me.context.close()
    assert me.unexpected_errors() == []

    # the instructor: the latest comparison (the bad log changed nothing) and the class's first differences
    r = httpx.get(f"{server.url}/api/assignments/{aid}/submissions/{sid}/trees", headers=TEACHER, timeout=30)
    assert r.status_code == 200, r.text
    kept = r.json()
    firsts = Counter(t["differences"][0]["what"] for t in kept["trees"] if t["differences"])
    assert firsts == {"eye_ray": 1}, firsts
    p = Page(browser, server, DESKTOP)
    p.allow.append(r"status of 401")  # the first load, before the token is in this browser's storage
    try:
        page = p.page
        page.goto(f"{server.url}/course")
        page.evaluate("(t) => localStorage.setItem('rt.instructor', JSON.stringify(t))", INSTRUCTOR)
        page.goto(f"{server.url}/course#{aid}/s1")
        page.wait_for_selector("#whats-svg g.bar")
        bars = page.eval_on_selector_all(
            "#whats-svg g.bar", "gs => gs.map(g => [g.dataset.what, Number(g.dataset.count)])"
        )
        assert dict(bars) == dict(firsts), bars
        rows = page.eval_on_selector_all(
            "#whats-table tbody tr", "rs => rs.map(r => [r.dataset.what, r.querySelector('td').textContent])"
        )
        assert rows == [["eye_ray", "1"]], rows
        assert "eye ray 1" in page.get_attribute("#whats-svg", "aria-label")
        page.click(f"#student-detail button.tl-open[data-sid='{sid}']")
        page.wait_for_selector("#student-detail .tl-box .tl-body[data-drawn=true]")
        seen = page.evaluate(SIDES, "#student-detail .tl-box")
        assert seen["what"] == "eye_ray" and seen["at"] == [x, y], seen
        assert "Your" not in seen["message"] and "The student's" in seen["message"], seen["message"]
        assert [s["title"] for s in seen["sides"]] == ["The student's tree", "The reference's tree"], seen
        assert [s["differs"] for s in seen["sides"]] == [[0], [0]] and seen["top"][0] == seen["top"][1], seen
        assert seen["width"] <= DESKTOP["width"], f"the page is {seen['width']} px wide at 1280"
        page.locator("#student-detail .tl-box").scroll_into_view_if_needed()
        page.screenshot(path=str(SHOTS / "own-tracer-instructor.png"))
        page.locator(".board-whats").screenshot(path=str(SHOTS / "own-tracer-whats.png"))
        assert_accessible(page, "own tracer, the instructor's view", "#student-detail .tl-box")
        assert_accessible(page, "own tracer, the class's first differences", ".board-whats")
    finally:
        p.context.close()
    assert p.unexpected_errors() == []
