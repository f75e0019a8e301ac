"""The web page in a real browser: Playwright driving Debian's Chromium (headless) against `python -m server`.

Each test opens the page in a fresh browser context (empty localStorage: a new student, whose token the
server issues with their first job) and fails on any console error or uncaught exception the page did not
expect, a violation of the content security policy included. The server has an instructor token, as a
class's server would: the test's own requests for a page's jobs carry it (`TEACHER`). Screenshots are
written to $WEB_SHOTS (default /tmp/web_shots) for a person to look at. These tests never skip: without
Playwright or Chromium they fail and say what is missing (`./dev test` installs both).
"""

from __future__ import annotations

import json
import re
import time
from collections import Counter
from pathlib import Path

import httpx

from tests.support.api import bearer
from tests.support.page import (
    DESKTOP,
    PHONE,
    SHOTS,
    TEACHER,
    Page,
    editor_text,
    radiosity_scene,
    render,
    run_lesson,
    set_scene,
    whitted,
)
from tests.support.scene import ROOT, scene_dict, small


def set_range(page, selector: str, value: int) -> None:
    page.eval_on_selector(selector, "(el, v) => { el.value = String(v); el.dispatchEvent(new Event('input')); }", value)


def line_of(text: str, needle: str) -> int:
    return text[: text.index(needle)].count("\n") + 1


def canvas_pixels(page, selector: str, colour: str | None = None) -> int:
    """Pixels of a canvas that differ from its dark background (or, with `colour` '#rrggbb', are near it)."""
    return page.evaluate(
        """([sel, colour]) => {
            const c = document.querySelector(sel);
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            const want = colour ? [1, 3, 5].map(i => parseInt(colour.slice(i, i + 2), 16)) : null;
            let n = 0;
            for (let i = 0; i < d.length; i += 4) {
                const ref = want || [16, 21, 28];  // the canvases' background is #10151c
                const diff = Math.abs(d[i] - ref[0]) + Math.abs(d[i+1] - ref[1]) + Math.abs(d[i+2] - ref[2]);
                if (want ? diff < 40 : diff > 30) n++;
            }
            return n;
        }""",
        [selector, colour],
    )


def canvas_grid(page, selector: str, cells: int = 16) -> list[float]:
    """A canvas as cells x cells mean brightness values (0..255): enough to tell two pictures apart."""
    return page.evaluate(
        """([sel, cells]) => {
            const c = document.querySelector(sel);
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            const out = new Array(cells * cells).fill(0);
            const n = new Array(cells * cells).fill(0);
            for (let y = 0; y < c.height; y++) for (let x = 0; x < c.width; x++) {
                const i = 4 * (y * c.width + x);
                const k = Math.floor(y * cells / c.height) * cells + Math.floor(x * cells / c.width);
                out[k] += (d[i] + d[i + 1] + d[i + 2]) / 3;
                n[k]++;
            }
            return out.map((v, k) => v / Math.max(1, n[k]));
        }""",
        [selector, cells],
    )


def rad_step(page, step: int) -> None:
    set_range(page, "#rad-step", step)
    page.wait_for_function(f"() => document.querySelector('#rad-mesh').dataset.step === '{step}'")


# --------------------------------------------------------------------------------------------------


def test_web_page_editor_marks_errors_at_their_line_and_keeps_unsaved_work(desktop):
    page = desktop.open().page
    # the example's scene arrived before anything is typed (else it replaces the typing: a CI run typed first)
    with page.expect_response(lambda r: r.url.endswith("/api/scenes/whitted")):
        page.select_option("#example-select", "whitted")
    page.wait_for_function("() => document.querySelector('#load-note').textContent.startsWith('Loaded whitted')")
    page.wait_for_selector("#validation-status[data-kind=ok]")
    assert json.loads(editor_text(page)) == scene_dict("whitted")

    # an invalid value and an undefined material: each reported at its own line, with its message
    text = editor_text(page)
    glass = text.index('"name": "glass ball"')
    bad = text[:glass] + text[glass:].replace('"radius": 1,', '"radius": -1,', 1).replace('"glass"', '"glas"', 1)
    page.fill("#scene-text", bad)
    page.wait_for_selector("#validation-status[data-kind=error]")
    radius_line = line_of(bad, '"radius": -1')
    material_line = line_of(bad, '"material": "glas"')
    page.wait_for_selector(f".backdrop .mark.error[data-line='{radius_line}']")
    marks = {int(m.get_attribute("data-line")): m.inner_text() for m in page.locator(".backdrop .mark").all()}
    assert "must be > 0" in marks[radius_line]
    assert "did you mean 'glass'" in marks[material_line]
    problems = page.locator("#problems li").all_inner_texts()
    assert any(f"line {radius_line}" in p and "objects[2].radius" in p for p in problems), problems
    assert page.locator(f".gutter-marks .gmark.error:text-is('{radius_line}')").count() == 1
    page.click(f"#problems li:has-text('line {radius_line}') button")  # jumps to the value
    selected = page.evaluate(
        "() => { const t = document.querySelector('#scene-text'); "
        "return t.value.slice(t.selectionStart, t.selectionEnd); }"
    )
    assert selected == "-1"
    desktop.shot("editor-error")

    # a JSON syntax error: its line and column, without asking the server
    broken = text.replace('"vfov": 40', '"vfov": 40,,', 1)
    page.fill("#scene-text", broken)
    page.wait_for_selector(".backdrop .mark .squiggle")
    line = line_of(broken, ",,")
    col = broken.split("\n")[line - 1].index(",,") + 2
    assert page.inner_text("#validation-status").startswith(f"JSON syntax error at line {line}, column {col}")
    assert page.locator(".backdrop .mark.error").get_attribute("data-line") == str(line)
    assert page.locator("#fs-camera input").first.is_disabled()
    desktop.shot("editor-syntax-error")

    # unsaved work survives a reload
    page.reload()
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert editor_text(page) == broken
    page.wait_for_selector(".backdrop .mark .squiggle")


def test_web_page_editor_names_the_example_wraps_its_messages_and_blanks_a_stale_form(desktop):
    """A first visit: the Example menu names the example the editor holds (Whitted's). An inline error wraps
    inside the visible width, right of the lines it spans (never cut at the panel's edge, never over the
    text). While the JSON does not parse, the form shows no value of an older text, and says why."""
    page = desktop.open().page
    page.wait_for_selector("#validation-status[data-kind=ok]")
    title = scene_dict("whitted")["name"]  # the menu's label of the example (GET /api/scenes: its name)
    assert page.eval_on_selector("#example-select", "s => [s.value, s.options[s.selectedIndex].text]") == [
        "whitted",
        title,
    ]

    text = editor_text(page)
    bad = text.replace('"type": "sphere"', '"type": "spher"', 1).replace('"width": 320', '"width": 32000', 1)
    page.fill("#scene-text", bad)
    line = line_of(bad, '"spher"')
    page.wait_for_selector(f".backdrop .mark.error[data-line='{line}'] .msg")
    page.click(f"#problems li:has-text('line {line}') button")  # scrolls the line into view
    boxes = page.evaluate(
        f"""() => {{
            const box = (el) => el.getBoundingClientRect();
            const mark = document.querySelector(".backdrop .mark[data-line='{line}']");
            const msg = mark.querySelector(".msg"), ghost = mark.querySelector(".ghost");
            return {{msg: box(msg), area: box(document.querySelector(".code-area")), text: msg.textContent,
                     clip: getComputedStyle(msg).textOverflow, char: box(ghost).width / ghost.textContent.length}};
        }}"""
    )
    msg, area = boxes["msg"], boxes["area"]
    assert "unknown object type 'spher'; expected one of: sphere, plane" in boxes["text"]
    assert boxes["clip"] != "ellipsis"
    assert area["left"] < msg["left"] and msg["right"] <= area["right"] + 0.5, boxes  # inside the visible width
    assert msg["height"] >= 2 * 20, boxes  # wrapped onto rows of the code's height (20 px)
    spanned = bad.split("\n")[line - 1 : line - 1 + round(msg["height"] / 20)]
    text_right = area["left"] + 10 + max(len(x) for x in spanned) * boxes["char"]  # the textarea's padding: 10 px
    assert msg["left"] >= text_right - 0.5, (spanned, boxes)  # right of every line it spans: never over the code
    desktop.shot("editor-error-wraps")

    broken = bad.replace('"vfov": 40', '"vfov": 40,,', 1)
    page.fill("#scene-text", broken)
    page.wait_for_selector("#fs-film:disabled", state="attached")
    shown = page.eval_on_selector_all(
        "#fields-form input, #fields-form select",
        "els => els.filter(e => e.type === 'checkbox' ? e.checked : e.value !== '').map(e => e.id || e.outerHTML)",
    )
    assert shown == [], shown  # not the width of 32000 nor any value of the text before the syntax error
    assert "once the text parses" in page.inner_text("#fields-form .note.warn")
    page.locator("#fields-form").scroll_into_view_if_needed()
    desktop.shot("editor-syntax-error-form")
    page.fill("#scene-text", bad)
    page.wait_for_selector("#form-stale-note[hidden]", state="attached")
    assert page.input_value("#fs-film .field[data-path='film.width'] input") == "32000"


def test_web_page_form_controls_write_into_the_json(desktop):
    page = desktop.open().page
    set_scene(page, whitted())
    page.fill("#fs-camera [data-path='camera.vfov'] input", "55")
    page.wait_for_function("() => document.querySelector('#scene-text').value.includes('\"vfov\": 55')")
    # a field the scene does not have is added to its section
    page.fill("#fs-render [data-path='render.light_samples'] input", "4")
    page.wait_for_function("() => document.querySelector('#scene-text').value.includes('\"light_samples\": 4')")
    # the glass ball's material, and a light's position
    page.select_option("#field-object", "2")
    page.fill("#fs-material [data-path='materials.glass.kd'] input", "0.1, 0.2, 0.3")
    page.fill("#fs-light [aria-label='position y']", "9")
    page.wait_for_function("() => document.querySelector('#scene-text').value.includes('\"position\": [4, 9, 5]')")
    page.select_option("#fs-sampler select", "adaptive")
    page.wait_for_selector("#fs-sampler [data-path='sampler.max_level']")
    page.wait_for_selector("#validation-status[data-kind=warn], #validation-status[data-kind=ok]")
    scene = json.loads(editor_text(page))
    assert scene["camera"]["vfov"] == 55
    assert scene["render"]["light_samples"] == 4
    assert scene["materials"]["glass"]["kd"] == [0.1, 0.2, 0.3]
    assert scene["lights"][0]["position"] == [4, 9, 5]
    assert scene["sampler"]["type"] == "adaptive"
    # the rest of the text kept its layout: only the edited values changed
    original = json.dumps(whitted(), indent=2)
    assert editor_text(page).split('"objects"')[1] == original.split('"objects"')[1]
    desktop.shot("editor-form")


def field_input(page, path: str) -> dict:
    """The attributes of a form field's (first) input or select, and whether it shows a default."""
    page.wait_for_selector(f"[data-path='{path}']")
    return page.eval_on_selector(
        f"[data-path='{path}']",
        """el => { const i = el.querySelector('input, select');
            return {tag: i.tagName.toLowerCase(), type: i.type, min: i.getAttribute('min'), max: i.getAttribute('max'),
                    step: i.getAttribute('step'), value: i.value, isDefault: el.classList.contains('is-default'),
                    options: [...el.querySelectorAll('option')].map(o => o.value), title: el.title}; }""",
    )


def test_web_page_form_rules_come_from_the_schema(desktop, server):
    page = desktop.open().page
    schema = httpx.get(f"{server.url}/api/schema", timeout=30).json()
    sampler = schema["$defs"]["Sampler"]["properties"]
    set_scene(page, small(whitted(), sampler={"type": "adaptive"}))
    # bounds: max_level allows what the scene format allows (8), no copy of its own
    level = field_input(page, "sampler.max_level")
    assert (level["min"], level["max"], level["step"]) == ("0", str(sampler["max_level"]["maximum"]), "1")
    assert level["value"] == str(sampler["max_level"]["default"])
    assert level["isDefault"]
    assert level["title"] == sampler["max_level"]["description"]
    # choices, exclusive bounds (0 < vfov < 180, a spinner step of 1), defaults, the kind of a field
    assert field_input(page, "sampler.type")["options"] == sampler["type"]["enum"]
    vfov = field_input(page, "camera.vfov")
    assert (vfov["min"], vfov["max"]) == ("1", "179")
    assert field_input(page, "render.integrator")["options"] == ["whitted", "path", "radiosity"]
    point = field_input(page, "lights.0.intensity")  # a number or r, g, b: a text field
    assert point["tag"] == "input"
    assert point["type"] == "text"
    # spp's default depends on the sampler type, as the schema says (x-default-by-type)
    for kind, want in sampler["spp"]["x-default-by-type"].items():
        set_scene(page, {**whitted(), "sampler": {"type": kind}})
        page.wait_for_function(
            """want => { const el = document.querySelector("[data-path='sampler.spp']");
                return el.classList.contains('is-default') && el.querySelector('input').value === want; }""",
            arg=str(want),
        )
    # another server's rules: the form follows them
    schema["$defs"]["Sampler"]["properties"]["max_level"]["maximum"] = 5
    schema["$defs"]["Sampler"]["properties"]["type"]["enum"].append("sobol")
    page.route("**/api/schema", lambda route: route.fulfill(json=schema))
    page.reload()
    page.wait_for_selector("body[data-ready=true]", state="attached")
    set_scene(page, {**whitted(), "sampler": {"type": "adaptive"}})
    assert field_input(page, "sampler.max_level")["max"] == "5"
    assert "sobol" in field_input(page, "sampler.type")["options"]
    desktop.shot("editor-form-schema")


def test_web_page_progressive_render_ray_tree_three_views(desktop, server):
    page = desktop.open().page
    scene = whitted(160, 120, spp=256)  # long enough for several previews while it runs
    set_scene(page, scene)
    page.click("#btn-render")
    page.wait_for_selector("#stage[data-status=running]")
    page.wait_for_function("() => Number(document.querySelector('#render-img').dataset.previews) >= 1")
    desktop.shot("viewer-running")
    page.wait_for_selector("#stage[data-status=done]", timeout=60_000)
    # the image was replaced at least twice while the job ran, then once more at the end
    assert int(page.get_attribute("#render-img", "data-running-previews")) >= 2
    stats = page.inner_text("#job-stats")
    assert "4,915,200 / 4,915,200 (100%)" in stats, stats
    assert re.search(r"eye 4,915,200", page.inner_text("#job-rays"))
    assert "Done: 160 × 120" in page.inner_text("#viewer-message")
    desktop.shot("viewer-done")

    # downloads (fetched with the page's token) and AOVs
    job_id = page.get_attribute("#stage", "data-job")
    for link, fmt in (("#dl-png", "png"), ("#dl-exr", "exr")):
        href = page.get_attribute(link, "href")
        assert href == f"/api/jobs/{job_id}/image?format={fmt}"
        with page.expect_download() as caught:
            page.click(link)
        saved = caught.value
        assert saved.suggested_filename == re.sub(r"[^A-Za-z0-9_-]+", "_", scene["name"])[:40] + f".{fmt}"
        data = Path(saved.path()).read_bytes()
        assert data == httpx.get(server.url + href, headers=TEACHER, timeout=30).content
        assert data[:4] == (b"\x89PNG" if fmt == "png" else b"\x76\x2f\x31\x01")
    page.click("[data-aov=rays]")
    page.wait_for_function("() => document.querySelector('#aov-legend').textContent.includes('Rays traced per pixel')")
    page.wait_for_function(
        "() => { const i = document.querySelector('#render-img'); return i.complete && i.naturalWidth > 0; }"
    )
    legend = page.inner_text("#aov-legend")  # the job's own sampler, not another's
    assert "The jittered sampler gives every pixel the same 256 eye rays" in legend
    assert "adaptive" not in legend
    desktop.shot("viewer-aov-rays")
    page.click("[data-aov=image]")

    # a pixel of the glass ball: the tree in the diagram has as many rays as the API's tree
    x, y = 112, 70
    img = page.locator("#render-img").bounding_box()
    page.mouse.click(img["x"] + (x + 0.5) * img["width"] / 160, img["y"] + (y + 0.5) * img["height"] / 120)
    page.wait_for_selector("#rt-diagram .rt-node")
    tree = httpx.post(
        f"{server.url}/api/raytree", json={"scene": scene, "x": x, "y": y, "sample": 0}, timeout=30
    ).json()
    n = len(tree["nodes"])
    assert n >= 5
    assert {"reflection", "transmission", "shadow"} <= {node["kind"] for node in tree["nodes"]}
    assert page.locator("#rt-diagram .rt-node").count() == n
    assert page.inner_text("#rt-pixel") == f"pixel ({x}, {y})"
    # the status counts the rays by kind, singular and plural as English has them
    status = page.inner_text("#rt-status")
    words = {
        "eye": ("eye ray", "eye rays"),
        "reflection": ("reflection ray", "reflection rays"),
        "transmission": ("transmission ray", "transmission rays"),
        "shadow": ("shadow ray reaching the light", "shadow rays reaching the light"),
        "blocked": ("blocked shadow ray", "blocked shadow rays"),
    }
    kinds = Counter("blocked" if nd["kind"] == "shadow" and nd["occluded"] else nd["kind"] for nd in tree["nodes"])
    assert any(c > 1 for c in kinds.values())
    for kind, c in kinds.items():
        assert f"{c} {words[kind][c != 1]}" in status, status
    # the overlay draws every ray over the image; the 3D view draws the scene and the rays
    assert page.get_attribute("#rt-overlay", "data-rays") == str(n)
    assert canvas_pixels(page, "#rt-overlay", "#44a8ff") > 20  # reflection rays, in their colour
    assert canvas_pixels(page, "#rt-overlay", "#2ee6a6") > 20  # transmission rays
    assert int(page.get_attribute("#rt-3d", "data-lines")) > 10
    assert page.get_attribute("#rt-3d", "data-rays") == str(n)
    assert canvas_pixels(page, "#rt-3d") > 2000
    page.locator("#raytree").scroll_into_view_if_needed()
    desktop.shot("raytree", full_page=True)

    # hovering a node highlights the same ray everywhere and shows its numbers
    reflection = next(node for node in tree["nodes"] if node["kind"] == "reflection")
    page.hover(f"#rt-diagram .rt-node[data-id='{reflection['id']}']")
    page.wait_for_selector(f"#rt-diagram .rt-node.hl[data-id='{reflection['id']}']")
    assert page.inner_text("#rt-details h3") == f"Ray #{reflection['id']}"
    assert reflection["hit"]["object_name"] in page.inner_text("#rt-details")
    desktop.shot("raytree-hover", full_page=True)

    # the depth slider replays the tree one generation at a time
    set_range(page, "#rt-depth", 1)
    first = sum(1 for node in tree["nodes"] if node["depth"] <= 1)
    assert page.get_attribute("#rt-overlay", "data-rays") == str(first)
    assert page.locator("#rt-diagram .rt-node.future").count() == n - first
    set_range(page, "#rt-depth", max(node["depth"] for node in tree["nodes"]))

    # the 3D view orbits with the mouse and zooms with the wheel
    before = page.locator("#rt-3d").screenshot()
    box = page.locator("#rt-3d").bounding_box()
    page.mouse.move(box["x"] + 100, box["y"] + 100)
    page.mouse.down()
    page.mouse.move(box["x"] + 220, box["y"] + 140, steps=5)
    page.mouse.up()
    page.mouse.wheel(0, 300)
    time.sleep(0.2)
    assert page.locator("#rt-3d").screenshot() != before
    desktop.shot("raytree-3d-orbited", full_page=True)

    # keyboard: the image takes the arrow keys and Enter to choose a pixel
    page.focus("#render-img")
    page.keyboard.press("ArrowLeft")
    page.keyboard.press("Enter")
    page.wait_for_function(f"() => document.querySelector('#rt-pixel').textContent === 'pixel ({x - 1}, {y})'")
    page.wait_for_function("() => document.querySelectorAll('#rt-diagram .rt-node').length > 0")


def test_web_page_rays_legend_follows_the_job_s_sampler(desktop):
    """The rays-per-pixel AOV's legend explains the differences with the sampler the job used."""
    page = desktop.open().page
    center = small(scene_dict("whitted"), 48, 36, sampler={"type": "center", "spp": 1})
    cases = [
        (small(scene_dict("antialias_adaptive"), 48, 36), "The adaptive sampler spends more eye rays"),
        (center, "The center sampler gives every pixel the same single eye ray"),
    ]
    for scene, says in cases:
        set_scene(page, scene)
        render(page)
        page.click("[data-aov=rays]")
        page.wait_for_function(
            "(says) => document.querySelector('#aov-legend').textContent.includes(says)", arg=says, timeout=10_000
        )
        page.click("[data-aov=image]")


def test_web_page_reference_and_api_links_work_offline(desktop, server):
    """The header's "Format reference" and "API" links open pages that need nothing from another host."""
    from urllib.parse import urlparse

    outside: list[str] = []

    def only_loopback(route) -> None:
        url = route.request.url
        if urlparse(url).scheme in ("http", "https") and urlparse(url).hostname != "127.0.0.1":
            outside.append(url)
            route.abort()
        else:
            route.continue_()

    desktop.context.route("**/*", only_loopback)
    page = desktop.open().page
    assert page.get_attribute("#editor-reference", "href") == "/reference/scene-format.md"
    page.click("#link-reference")
    page.wait_for_selector("h1:has-text('The scene format')")
    assert page.locator("main.doc table").count() > 20
    page.click("a[href='#camera-rays']")
    page.wait_for_function("() => location.hash === '#camera-rays'")
    desktop.shot("reference")
    page.go_back()
    page.go_back()
    page.wait_for_selector("body[data-ready=true]", state="attached")
    page.click("header a[href='/docs']")
    page.wait_for_selector("text=Submit a scene for rendering", timeout=30_000)  # Swagger UI read /openapi.json
    desktop.shot("api-docs")
    assert outside == []


def test_web_page_cancel_and_my_jobs(desktop):
    page = desktop.open().page
    set_scene(page, whitted(32, 24, spp=4))
    render(page)
    set_scene(page, whitted(192, 144, spp=1024))
    page.click("#btn-render")
    page.wait_for_selector("#stage[data-status=running]")
    page.wait_for_function("() => Number(document.querySelector('#render-img').dataset.previews) >= 1")
    page.click("#btn-cancel")
    page.wait_for_selector("#stage[data-status=cancelled]", timeout=30_000)
    # the status is set as the end arrives, the message once the last picture has loaded (viewer.js, ended)
    page.wait_for_function("() => document.querySelector('#viewer-message').innerText.includes('Cancelled after')")
    assert "Cancelled after" in page.inner_text("#viewer-message")
    assert page.locator("#job-list li[data-status]").count() == 2
    assert page.locator("#job-list li[data-status=done] img").count() == 1
    desktop.shot("viewer-cancelled")
    # my jobs survive a reload; opening the finished one shows it
    page.reload()
    page.wait_for_selector("body[data-ready=true]", state="attached")
    page.wait_for_selector("#job-list li[data-status=cancelled]")
    page.click("#job-list li[data-status=done] .job-open")
    page.wait_for_selector("#stage[data-status=done]")
    page.wait_for_function("() => document.querySelector('#render-img').naturalWidth === 32")


def job_ids(page) -> list[str]:
    return page.eval_on_selector_all("#job-list li[data-id]", "lis => lis.map(li => li.dataset.id)")


def test_web_page_each_student_sees_only_their_own_jobs(browser, server):
    """Two students, two browser contexts: each page keeps the token the server issued with its first job
    (localStorage), so its jobs survive a reload; neither page can list or open the other's jobs."""
    alice, bob = Page(browser, server, DESKTOP), Page(browser, server, DESKTOP)
    bob.allow = [r"status of 404"]  # Chromium logs the refused look at alice's job
    try:
        a = alice.open().page
        assert a.evaluate("() => localStorage.getItem('rt.token')") is None  # no token before the first job
        set_scene(a, whitted(32, 24, spp=4))
        render(a)
        a_job = a.get_attribute("#stage", "data-job")
        a_token = a.evaluate("() => JSON.parse(localStorage.getItem('rt.token'))")
        assert re.fullmatch(r"[A-Za-z0-9_-]{43}", a_token)
        assert httpx.get(f"{server.url}/api/jobs/{a_job}", headers=bearer(a_token)).json()["status"] == "done"
        assert httpx.get(f"{server.url}/api/jobs/{a_job}").status_code == 404  # the id alone opens nothing
        set_scene(a, whitted(40, 30, spp=4))
        render(a)
        assert a.evaluate("() => JSON.parse(localStorage.getItem('rt.token'))") == a_token  # one token, kept
        a_jobs = job_ids(a)
        assert len(a_jobs) == 2
        assert a_job in a_jobs

        b = bob.open().page
        set_scene(b, whitted(24, 18, spp=4))
        render(b)
        b_job = b.get_attribute("#stage", "data-job")
        b_token = b.evaluate("() => JSON.parse(localStorage.getItem('rt.token'))")
        assert b_token != a_token and job_ids(b) == [b_job]
        mine = httpx.get(f"{server.url}/api/jobs", headers=bearer(b_token)).json()
        assert [j["id"] for j in mine["jobs"]] == [b_job]
        # bob's page asks for alice's job: the answer of an id that does not exist
        answer = b.evaluate(
            """async (id) => {
                const { api } = await import('/js/api.js');
                try { await api.job(id); return 'shown'; } catch (e) { return [e.status, e.message]; }
            }""",
            a_job,
        )
        assert answer == [404, f"id: no job with id '{a_job}'"]
        # alice's id in bob's list (a copied link): gone from it after a reload, never shown
        b.evaluate(
            "(id) => localStorage.setItem('rt.jobs', JSON.stringify([id, ...JSON.parse(localStorage['rt.jobs'])]))",
            a_job,
        )
        b.reload()
        b.wait_for_selector("body[data-ready=true]", state="attached")
        b.wait_for_selector(f"#job-list li[data-id='{b_job}']")
        assert job_ids(b) == [b_job]
        assert a_job not in b.evaluate("() => localStorage.getItem('rt.jobs')")
        bob.shot("two-students-bob")

        # alice reloads: her jobs are still hers, the one shown comes back with its image
        a.reload()
        a.wait_for_selector("body[data-ready=true]", state="attached")
        a.wait_for_selector("#stage[data-status=done]")
        assert job_ids(a) == a_jobs
        a.wait_for_function("() => document.querySelector('#render-img').naturalWidth === 40")
        a.wait_for_function(
            "() => [...document.querySelectorAll('#job-list li img')].every(i => i.complete && i.naturalWidth > 0)"
        )
        assert a.locator("#job-list li img").count() == 2
        alice.shot("two-students-alice")
    finally:
        alice.context.close()
        bob.context.close()
    assert alice.unexpected_errors() == [] and bob.unexpected_errors() == []


def test_web_page_shows_a_queued_job_s_place_and_wait(desktop, server):
    """The only worker renders a long job (the batch lane, by its estimate): a job from the page says
    where it is in line, and runs as soon as the long render gives way at its next pass."""
    scene = {"scene": whitted(256, 192, spp=4096)}
    busy = httpx.post(f"{server.url}/api/jobs", json=scene, headers=TEACHER, timeout=30).json()
    try:
        wait_for_status = lambda: httpx.get(f"{server.url}/api/jobs/{busy['id']}", headers=TEACHER).json()["status"]  # noqa: E731
        deadline = time.monotonic() + 30
        while wait_for_status() != "running":
            assert time.monotonic() < deadline, "the long job did not start"
            time.sleep(0.05)
        page = desktop.open().page
        set_scene(page, whitted(32, 24, spp=4))
        page.click("#btn-render")
        page.wait_for_function("() => document.querySelector('#viewer-message').textContent.includes('in line')")
        text = page.inner_text("#viewer-message")  # the long render is batch work: it gives way at its next pass
        assert "Queued: next in line, starting in a moment" in text, text
        desktop.shot("viewer-queued")
    finally:
        httpx.delete(f"{server.url}/api/jobs/{busy['id']}", headers=TEACHER)
    page.wait_for_selector("#stage[data-status=done]", timeout=60_000)


def test_web_page_lessons(desktop, server):
    page = desktop.open("#lessons").page

    assert run_lesson(page, "bounces", 3) == ["done"] * 3
    page.wait_for_function(
        "() => [...document.querySelectorAll('.lesson-panel img')].every(i => i.complete && i.naturalWidth === 160)"
    )
    desktop.shot("lesson-bounces", full_page=True)

    answers = []  # the server's sample positions, as the page asked for them
    page.on("response", lambda r: "/api/samples" in r.url and answers.append((r.request.post_data, r.json())))
    assert run_lesson(page, "sampling", 4) == ["done"] * 4
    page.wait_for_function("() => [...document.querySelectorAll('canvas.samples')].every(c => c.dataset.positions)")
    canvases = page.locator(".lesson-panel canvas.samples").all()
    samples = [int(c.get_attribute("data-samples")) for c in canvases]
    assert samples[:2] == [1, 16] and samples[2] > 5 and samples[3] == 16, samples
    # each drawing shows the positions the server gave for the panel's own scene (adaptive: the traced ones)
    by_sampler = {}  # the answers come in any order
    for body, listed in answers:
        request = json.loads(body)
        assert request["scene"]["sampler"]["type"] == listed["sampler"]
        assert [request["x"], request["y"]] == listed["pixel"] == [44, 37]
        by_sampler[listed["sampler"]] = listed
    assert len(answers) == len(by_sampler) == 4
    for canvas, kind in zip(canvases, ["center", "grid", "adaptive", "jittered"], strict=True):
        listed = by_sampler[kind]
        traced = [s["position"] for s in listed["samples"] if s.get("traced", True)]
        assert json.loads(canvas.get_attribute("data-positions")) == traced
        words = canvas.locator("xpath=..").inner_text()
        assert words.startswith("pixel (44, 37): ")
        assert kind == "center" or f": {len(traced)} rays" in words
    desktop.shot("lesson-sampling", full_page=True)

    # radiosity: an image where the server has it, else the server's own message
    cornell = scene_dict("cornell_path")
    cornell["render"]["integrator"] = "radiosity"
    verdict = httpx.post(f"{server.url}/api/validate", json={"scene": cornell}, timeout=30).json()
    if not verdict["valid"]:
        desktop.allow.append(r"status of 422")  # Chromium logs the refused submission
    statuses = run_lesson(page, "integrators", 3)
    assert statuses[:2] == ["done", "done"]
    if verdict["valid"]:
        assert statuses[2] == "done"
    else:
        assert statuses[2] == "refused"
        assert verdict["errors"][0]["message"] in page.inner_text(".lesson-panel[data-status=refused]")
    desktop.shot("lesson-integrators", full_page=True)

    # a panel opens in the workspace with its scene and its job
    page.locator(".lesson-panel").first.get_by_role("button", name="Open in workspace").click()
    page.wait_for_selector("#page-work:not([hidden]) #stage[data-status=done]")
    assert json.loads(editor_text(page))["render"]["integrator"] == "whitted"


def canvas_colour(canvas, u: float, v: float) -> list[int]:
    """The RGB of a sampler picture at pixel position (u, v) (the pixel spans it but for an 8 px margin)."""
    return canvas.evaluate(
        """(c, [u, v]) => {
            const css = parseFloat(c.style.width), k = c.width / css, s = css - 16;
            const at = (t) => Math.round((8 + t * s) * k);
            return [...c.getContext('2d').getImageData(at(u), at(v), 1, 1).data].slice(0, 3);
        }""",
        [u, v],
    )


def test_web_page_sampler_pictures_draw_the_server_s_positions(desktop):
    """The pictures draw what POST /api/samples answers, nothing of their own: answers made up here are drawn."""
    page = desktop.page
    made_up = {
        "center": [[0.5, 0.5]],
        "grid": [[0.1, 0.1], [0.9, 0.1]],
        "adaptive": [[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]],
        "jittered": [[0.2, 0.8], [0.75, 0.3], [0.6, 0.6]],
    }

    def answer(route):
        kind = json.loads(route.request.post_data)["scene"]["sampler"]["type"]
        samples = [{"sample": k, "position": p, "weight": 1.0, "traced": True} for k, p in enumerate(made_up[kind])]
        cell = {"corner": [0, 0], "size": 1, "level": 0, "split": False, "srgb": "#204060"}
        listed = {"pixel": [1, 2], "sampler": kind, "strata": None, "max_level": 3, "samples": samples}
        route.fulfill(json={**listed, "cells": [cell] if kind == "adaptive" else None})

    page.route("**/api/samples", answer)
    desktop.open("#lessons")
    run_lesson(page, "sampling", 4)
    page.wait_for_function("() => [...document.querySelectorAll('canvas.samples')].every(c => c.dataset.positions)")
    for canvas, kind in zip(page.locator("canvas.samples").all(), made_up, strict=True):
        assert json.loads(canvas.get_attribute("data-positions")) == made_up[kind]
        for u, v in made_up[kind]:  # an orange dot at each position
            assert canvas_colour(canvas, u, v) == [255, 122, 0], (kind, u, v)
    # the adaptive sampler's cell, filled with the colour the server gave it
    assert canvas_colour(page.locator("canvas.samples").nth(2), 0.25, 0.75) == [32, 64, 96]
    assert "pixel (1, 2)" in page.inner_text(".lesson-panel >> nth=0")


def test_web_page_viewer_and_lessons_follow_jobs_the_same_way(desktop):
    """One followJob (web/js/jobs.js, on api.js's followEvents) follows jobs for the viewer and the lessons: a
    stream that keeps dropping is retried MAX_FAILURES (8) times by both, then given up with a message. It reads
    the stream with fetch (an EventSource cannot send the job's token), in api.js alone."""
    web = ROOT / "web" / "js"
    assert [p.name for p in web.glob("*.js") if "EventSource(" in p.read_text()] == []
    assert [p.name for p in web.glob("*.js") if "eventsUrl(" in p.read_text() and p.name != "api.js"] == ["jobs.js"]
    # api.js is the one HTTP client of every page: no other module fetches, or reads an event stream itself
    others = [p for p in sorted(web.rglob("*.js")) if p.name != "api.js"] + sorted((ROOT / "web").glob("*.html"))
    assert [p.name for p in others if "fetch(" in p.read_text() or "text/event-stream" in p.read_text()] == []
    for user in ("viewer.js", "lessons.js"):
        assert 'import { followJob } from "./jobs.js";' in (web / user).read_text(), user

    page = desktop.page
    desktop.allow = [r"net::ERR_FAILED"]
    tries = Counter()

    def drop(route):  # an empty stream that asks to be retried at once: each retry is one drop
        tries[route.request.url.split("/")[-2]] += 1
        route.fulfill(status=200, headers={"content-type": "text/event-stream"}, body="retry: 10\n\n")

    page.route("**/api/jobs/*/events", drop)
    desktop.open()
    set_scene(page, whitted(32, 24))
    page.click("#btn-render")
    page.wait_for_selector("#viewer-message[data-kind=error] button")
    assert "Lost the connection to the server" in page.inner_text("#viewer-message")
    assert list(tries.values()) == [8]
    page.click("#tab-lessons")
    assert run_lesson(page, "dof", 2) == ["failed", "failed"]
    assert all("lost the connection to the server" in t for t in page.locator(".lesson-panel").all_inner_texts())
    assert list(tries.values()) == [8, 8, 8]
    # the real stream again: the viewer's "Try again" shows the job, which has ended by now
    page.unroute("**/api/jobs/*/events")
    page.click("#tab-work")
    page.click("#viewer-message button")
    page.wait_for_selector("#stage[data-status=done]")


def test_web_page_phone_layout(phone):
    page = phone.open().page
    set_scene(page, whitted(80, 60, spp=4))
    phone.shot("phone-editor")
    render(page)
    page.locator("#render-img").scroll_into_view_if_needed()  # the mouse clicks only what the screen shows
    img = page.locator("#render-img").bounding_box()
    page.mouse.click(img["x"] + img["width"] * 0.7, img["y"] + img["height"] * 0.6)
    page.wait_for_selector("#rt-diagram .rt-node")
    width = page.evaluate("() => document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the page is {width} px wide on a {PHONE['width']} px screen"
    page.locator("#raytree").scroll_into_view_if_needed()
    phone.shot("phone-raytree")
    phone.shot("phone-full", full_page=True)
    page.click("#tab-lessons")
    assert run_lesson(page, "dof", 2) == ["done", "done"]
    assert page.evaluate("() => document.documentElement.scrollWidth") <= PHONE["width"]
    phone.shot("phone-lesson", full_page=True)


def test_web_page_keyboard_reaches_the_controls(desktop):
    page = desktop.open().page
    reached = []
    for _ in range(12):
        page.keyboard.press("Tab")
        reached.append(
            page.evaluate("() => document.activeElement.id || document.activeElement.textContent.trim().slice(0, 20)")
        )
    for want in ("tab-work", "example-select", "btn-open-file", "scene-text"):
        assert want in reached, reached
    # focus is visible (an outline or a ring), and the tabs move with the arrow keys
    page.focus("#tab-work")
    page.keyboard.press("ArrowRight")
    assert page.evaluate("() => document.activeElement.id") == "tab-lessons"
    assert page.is_visible("#page-lessons")
    outline = page.evaluate("() => getComputedStyle(document.activeElement).outlineStyle")
    assert outline != "none"


def test_web_page_broken_server_and_failed_job_show_messages(desktop):
    page = desktop.page
    desktop.allow = [r"net::ERR_FAILED", r"status of 422"]
    # the server stops answering the API: the page says so (and the editor still works)
    page.route("**/api/**", lambda route: route.abort())
    desktop.open()
    page.wait_for_selector("#banner:not([hidden])")
    assert "Could not reach the server" in page.inner_text("#banner")
    assert page.locator("#scene-text").is_visible()
    page.fill("#scene-text", json.dumps(whitted()))
    page.wait_for_function("() => document.querySelector('#fs-film input').value === '160'")  # the form follows
    page.wait_for_selector("#validation-status[data-kind=warn]")
    assert "not answering" in page.inner_text("#validation-status")
    desktop.shot("broken-server")
    page.unroute("**/api/**")

    # a job that fails: its reason is shown, not a blank viewer
    failed = {
        "id": "F" * 22, "status": "failed", "finished": True, "priority": 0, "name": "broken",
        "width": 32, "height": 24, "created_at": "2026-01-01T00:00:00Z", "started_at": None, "finished_at": None,
        "progress": {
            "samples_done": 0, "samples_total": 3072, "fraction": 0, "passes_done": 0, "spp_done": 0, "spp_total": 4,
        },
        "elapsed": 0.1, "eta": None, "rays": {}, "preview": 0, "image_url": None,
        "events_url": f"/api/jobs/{'F' * 22}/events", "error": "render error: RuntimeError: out of memory",
        "errors": [], "warnings": [], "attempts": 2, "cancel_requested": False,
    }  # fmt: skip
    queued = {**failed, "status": "queued", "finished": False, "error": None}
    page.route(
        "**/api/jobs",
        lambda route: route.fulfill(status=202, json=queued) if route.request.method == "POST" else route.continue_(),
    )
    page.route(
        "**/api/jobs/*/events",
        lambda route: route.fulfill(
            status=200,
            headers={"content-type": "text/event-stream"},
            body=f"event: end\ndata: {json.dumps(failed)}\n\n",
        ),
    )
    page.click("#btn-render")
    page.wait_for_selector("#viewer-message[data-kind=error]")
    assert "The job failed: render error: RuntimeError: out of memory" in page.inner_text("#viewer-message")
    assert page.get_attribute("#stage", "data-status") == "failed"
    desktop.shot("failed-job")

    # a lesson panel the server refuses shows the server's message, not an image
    refusal = {
        "errors": [{"path": "render.integrator", "message": "the 'radiosity' integrator is not implemented yet"}]
    }

    def jobs(route):
        if route.request.method == "POST" and '"radiosity"' in (route.request.post_data or ""):
            route.fulfill(status=422, json=refusal)
        else:
            route.continue_()

    page.unroute("**/api/jobs")
    page.route("**/api/jobs", jobs)
    page.unroute("**/api/jobs/*/events")
    page.click("#tab-lessons")
    assert run_lesson(page, "integrators", 3) == ["done", "done", "refused"]
    refused = page.inner_text(".lesson-panel[data-status=refused]")
    assert "The server refused this scene" in refused
    assert "integrator is not implemented yet" in refused
    assert page.locator(".lesson-panel[data-status=refused] img").is_hidden()
    desktop.shot("lesson-refused")


def test_web_page_radiosity_panel_steps_through_the_solution(desktop, server):
    page = desktop.open().page
    scene = radiosity_scene()
    set_scene(page, scene)
    render(page)
    assert page.get_attribute("#stage", "data-status") == "done"
    page.wait_for_selector("#radiosity:not([hidden]) #rad-body:not([hidden])")
    job_id = page.get_attribute("#stage", "data-job")
    sol = httpx.get(f"{server.url}/api/jobs/{job_id}/radiosity", headers=TEACHER, timeout=30).json()
    history, sides = sol["history"], len(sol["radiosity"])
    steps, n = len(history), sides // 2
    assert steps > 20
    assert isinstance(history[0]["shooter"], str)
    assert isinstance(history[1]["shooter"], int)
    assert page.get_attribute("#radiosity", "data-steps") == str(steps)
    assert f"{n} patches ({sides} sides) · {steps} shots" in page.inner_text("#rad-summary")

    def object_name(side: int) -> str:
        obj = scene["objects"][sol["patches"]["object"][side % n]]
        return obj["name"]

    # it opens on the final solution: the whole mesh drawn, lit, with the last shooter outlined
    mesh = page.locator("#rad-mesh")
    assert mesh.get_attribute("data-step") == str(steps)
    assert mesh.get_attribute("data-snapshot") == str(steps)
    assert int(mesh.get_attribute("data-patches")) > n // 3
    assert canvas_pixels(page, "#rad-mesh") > 20_000
    last = history[-1]["shooter"]
    assert page.inner_text("#rad-step-out") == f"B after {steps} of {steps} shots"
    assert f"Shot {steps} of {steps}: patch {last} (" in page.inner_text("#rad-shot")
    assert f"object '{object_name(last)}'" in page.inner_text("#rad-shot")
    desktop.shot("radiosity-final", full_page=True)
    final = canvas_grid(page, "#rad-mesh")

    # step 1: the light has shot, nothing else: darker (no interreflection, a black ceiling), and it says so
    rad_step(page, 1)
    assert page.inner_text("#rad-shot").startswith(f"Shot 1 of {steps}: lights[0] (quad) shoots its power")
    assert mesh.get_attribute("data-shooter") == "lights[0]"
    assert page.inner_text("#rad-step-out") == f"B after 1 of {steps} shots"
    first = canvas_grid(page, "#rad-mesh")
    changed = sum(1 for a, b in zip(first, final, strict=True) if abs(a - b) > 6)
    assert changed > 40, f"only {changed} of 256 cells changed between step 1 and step {steps}"
    assert sum(final) > sum(first) * 1.1  # the indirect light adds up
    page.locator("#radiosity").screenshot(path=str(SHOTS / "radiosity-step1.png"))

    # step 2: the first patch shoots; it is outlined in orange, its number and object named
    rad_step(page, 2)
    shooter = history[1]["shooter"]
    label = page.inner_text("#rad-shot")
    assert f"Shot 2 of {steps}: patch {shooter} (" in label and f"object '{object_name(shooter)}'" in label, label
    assert f"shoots {history[1]['power']:.3g} W; " in label, label
    assert mesh.get_attribute("data-shooter") == str(shooter)
    assert canvas_pixels(page, "#rad-mesh", "#ff9f1c") > 30
    # between two snapshots the last one before the step is shown, and said so
    keys = sorted(int(k) for k in sol["snapshots"])
    between = next(k for k in range(17, steps) if k not in keys)
    rad_step(page, between)
    before = max(k for k in keys if k <= between)
    assert mesh.get_attribute("data-snapshot") == str(before)
    shown = page.inner_text("#rad-step-out")
    assert shown == f"B after {before} of {steps} shots (the last snapshot before step {between})", shown
    assert page.input_value("#rad-step-num") == str(between)

    # the keyboard drives the slider
    page.focus("#rad-step")
    page.keyboard.press("Home")
    page.wait_for_function("() => document.querySelector('#rad-mesh').dataset.step === '0'")
    assert page.inner_text("#rad-step-out") == "B before any shot: the emitters only"
    assert canvas_pixels(page, "#rad-mesh", "#ff9f1c") < 10  # nobody has shot
    page.keyboard.press("ArrowRight")
    page.wait_for_function("() => document.querySelector('#rad-mesh').dataset.step === '1'")
    page.keyboard.press("End")
    page.wait_for_function(f"() => document.querySelector('#rad-mesh').dataset.step === '{steps}'")

    # clicking the curve goes to that step (the plot spans x = 50 .. width - 14 px)
    curve = page.locator("#rad-curve").bounding_box()
    page.locator("#rad-curve").click(position={"x": 50 + 0.5 * (curve["width"] - 64), "y": curve["height"] / 2})
    clicked = int(page.input_value("#rad-step"))
    assert abs(clicked - steps / 2) <= 1, (clicked, steps)
    assert page.get_attribute("#rad-curve", "data-step") == str(clicked)
    assert page.inner_text("#rad-shot").startswith(f"Shot {clicked} of {steps}: ")

    # the energy balance of the final solution: emitted = absorbed + unshot + escaped
    energy = sol["energy"]
    total = sum(energy["emitted"])
    assert abs(total - sum(sum(energy[k]) for k in ("absorbed", "unshot", "escaped"))) < 1e-3 * total
    assert page.locator(".rad-energy tbody tr").count() == 4
    assert page.inner_text(".rad-energy tr[data-row=emitted] td:nth-child(5)") == f"{total:.3g}"
    assert page.inner_text(".rad-balance").startswith(f"emitted {total:.4g} W = absorbed ")

    # mesh lines off: the same colours without the outlines
    with_lines = canvas_grid(page, "#rad-mesh", 32)
    page.uncheck("#rad-lines")
    without = canvas_grid(page, "#rad-mesh", 32)
    assert sum(1 for a, b in zip(with_lines, without, strict=True) if abs(a - b) > 1) > 50

    # play steps on by itself; pause stops it
    page.click("#rad-prev")
    start = int(page.input_value("#rad-step"))
    page.click("#rad-play")
    page.wait_for_function(f"() => Number(document.querySelector('#rad-step').value) >= {start + 3}")
    page.click("#rad-play")
    assert page.inner_text("#rad-play") == "▶ Play"
    stopped = page.input_value("#rad-step")
    time.sleep(0.3)
    assert page.input_value("#rad-step") == stopped

    # a job of another integrator: no panel; the radiosity job from "my jobs" brings it back
    set_scene(page, whitted(32, 24, spp=4))
    render(page)
    time.sleep(0.3)
    assert page.is_hidden("#radiosity")
    page.click(f"#job-list li[data-id='{job_id}'] .job-open")
    page.wait_for_selector("#radiosity:not([hidden]) #rad-body:not([hidden])")
    assert page.get_attribute("#rad-mesh", "data-step") == str(steps)
    page.click("#job-list li:not(.current) .job-open")
    page.wait_for_function("() => document.querySelector('#stage').dataset.job !== " + json.dumps(job_id))
    time.sleep(0.3)
    assert page.is_hidden("#radiosity")


def test_web_page_radiosity_panel_on_a_phone(phone):
    page = phone.open().page
    set_scene(page, radiosity_scene())
    render(page)
    page.wait_for_selector("#radiosity:not([hidden]) #rad-body:not([hidden])")
    panel = page.locator("#radiosity").bounding_box()
    for canvas in ("#rad-mesh", "#rad-curve"):
        box = page.locator(canvas).bounding_box()
        assert box["width"] > 0.7 * panel["width"] and box["x"] + box["width"] <= panel["x"] + panel["width"], canvas
    assert canvas_pixels(page, "#rad-mesh") > 5_000
    # nothing in the panel sticks out of the screen
    wide = page.evaluate(
        """(w) => [document.querySelector('#radiosity'), ...document.querySelectorAll('#radiosity *')]
            .filter(e => e.getBoundingClientRect().right > w + 0.5).map(e => e.id || e.tagName)""",
        PHONE["width"],
    )
    assert wide == [], f"wider than the {PHONE['width']} px screen: {wide}"
    # a tap on the curve sets the step (the plot spans x = 50 .. width - 14 px)
    steps = int(page.get_attribute("#radiosity", "data-steps"))
    curve = page.locator("#rad-curve").bounding_box()
    page.locator("#rad-curve").click(position={"x": 50 + 0.25 * (curve["width"] - 64), "y": 60})
    page.wait_for_function(f"() => document.querySelector('#rad-mesh').dataset.step !== '{steps}'")
    assert abs(int(page.input_value("#rad-step")) - steps / 4) <= 2
    assert page.inner_text("#rad-shot").startswith(f"Shot {page.input_value('#rad-step')} of {steps}: patch ")
    page.locator("#radiosity").scroll_into_view_if_needed()
    phone.shot("phone-radiosity")
    page.locator("#radiosity").screenshot(path=str(SHOTS / "phone-radiosity-panel.png"))
