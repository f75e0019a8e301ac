"""The lessons in a real browser: Playwright driving Debian's Chromium (headless) against `python -m server`.

For every lesson of web/js/lessons.js (the entries in web/js/lessons/): open it, let its panels render through the
job API, change one of its controls and see the panels it touches render again into different pictures (their old
jobs superseded), with what changed and what it cost written under each; then answer its question wrongly and
rightly. Any console error or uncaught exception fails the test (the fixtures are those of test_web_page.py).
Screenshots of each lesson are written to $WEB_SHOTS (default /tmp/web_shots) for a person to look at.
"""

from __future__ import annotations

import json
import re
from io import BytesIO

import httpx
import numpy as np
import pytest
from PIL import Image

from tests.support.api import wait_finished
from tests.support.page import DESKTOP, PHONE, TEACHER, Page
from tests.support.scene import ROOT

JS = ROOT / "web" / "js"


def lesson_ids() -> list[str]:
    """The ids of LESSONS in order: web/js/lessons.js puts together the lists of its topics' files (lessons/)."""
    engine = (JS / "lessons.js").read_text()
    files = dict(re.findall(r'^import \{ (\w+) \} from "\./(lessons/[\w-]+\.js)";$', engine, re.M))
    order = re.findall(r"\.\.\.(\w+)", re.search(r"^export const LESSONS = \[(.*)\];$", engine, re.M)[1])
    return [i for name in order for i in re.findall(r'^    id: "([\w-]+)",$', (JS / files[name]).read_text(), re.M)]


LESSON_IDS = lesson_ids()
ENDED = "['done', 'refused', 'failed', 'cancelled'].includes(p.dataset.status)"


@pytest.fixture
def desktop(browser, server):
    p = Page(browser, server, DESKTOP)
    yield p
    p.context.close()
    assert p.unexpected_errors() == []


def open_lesson(page, lesson: str) -> None:
    page.click(f".lesson-button[data-lesson={lesson}]")
    panels_ended(page, lesson)


def panels_ended(page, lesson: str) -> None:
    """The lesson on the stage, with every panel's job ended."""
    page.wait_for_function(
        f"""() => document.querySelector('#lesson-stage').dataset.lesson === '{lesson}'
            && document.querySelectorAll('.lesson-panel').length > 0
            && [...document.querySelectorAll('.lesson-panel')].every(p => {ENDED})""",
        timeout=120_000,
    )


def pictures_loaded(page) -> None:
    """Every panel's picture shows its job's final image (a blob: the page fetched it with the token)."""
    page.wait_for_function(
        """() => [...document.querySelectorAll('.lesson-panel')].every(p => {
            const i = p.querySelector('img.lesson-picture');
            return p.dataset.status === 'done' && i.dataset.shown === p.dataset.image
                && i.src === i.dataset.blob && i.complete && i.naturalWidth > 0;
        })""",
        timeout=60_000,
    )


def fingerprints(page) -> list[str]:
    """A hash of each panel picture's pixels."""
    return page.evaluate(
        """() => [...document.querySelectorAll('.lesson-panel img.lesson-picture')].map(img => {
            const c = document.createElement('canvas');
            c.width = img.naturalWidth; c.height = img.naturalHeight;
            const ctx = c.getContext('2d');
            ctx.drawImage(img, 0, 0);
            const d = ctx.getImageData(0, 0, c.width, c.height).data;
            let h = 2166136261;
            for (let i = 0; i < d.length; i++) { h ^= d[i]; h = Math.imul(h, 16777619) >>> 0; }
            return `${c.width}x${c.height}:${h}`;
        })"""
    )


def job_png(server, job_id: str) -> np.ndarray:
    """A job's final picture as it was sent (0-255 RGB floats)."""
    r = httpx.get(f"{server.url}/api/jobs/{job_id}/image?format=png", headers=TEACHER, timeout=30)
    r.raise_for_status()
    return np.asarray(Image.open(BytesIO(r.content)).convert("RGB"), dtype=np.float64)


def panel_texts(page, selector: str) -> list[str]:
    return [el.inner_text() for el in page.locator(f".lesson-panel {selector}").all()]


def change_control(page, lesson: str) -> list[int]:
    """Change the lesson's first control to another value; the indices of the panels it touches."""
    spec = page.evaluate(
        """async (id) => {
            const { LESSONS } = await import('/js/lessons.js');
            const l = LESSONS.find(x => x.id === id);
            const c = l.controls[0];
            return { key: c.key, kind: c.kind, value: c.value, min: c.min, max: c.max,
                     choices: c.choices ? c.choices.map(([v]) => JSON.stringify(v)) : null,
                     panels: c.panels || l.panels.map((_, i) => i) };
        }""",
        lesson,
    )
    control = page.locator(f".lesson-controls [data-key={spec['key']}]")
    if spec["kind"] == "range":
        value = spec["max"] if spec["value"] != spec["max"] else spec["min"]
        control.fill(str(value))  # an input event, as a drag would give
    else:
        current = json.dumps(spec["value"], separators=(",", ":"))
        control.select_option([v for v in spec["choices"] if v != current][0])
    return spec["panels"]


def answer_question(page) -> None:
    page.wait_for_selector(".lesson-question .choice", timeout=60_000)
    answer = page.evaluate("() => document.querySelector('.lesson-question').question.answer")
    n = page.locator(".lesson-question .choice").count()
    assert n >= 2
    assert 0 <= answer < n
    wrong = (answer + 1) % n
    page.click(f".lesson-question .choice[data-choice='{wrong}']")
    assert page.get_attribute(".lesson-question .feedback", "data-verdict") == "wrong"
    assert "Not quite" in page.inner_text(".lesson-question .feedback")
    assert page.get_attribute(f".lesson-question .choice[data-choice='{wrong}']", "data-verdict") == "wrong"
    page.click(f".lesson-question .choice[data-choice='{answer}']")
    assert page.get_attribute(".lesson-question .feedback", "data-verdict") == "right"
    feedback = page.inner_text(".lesson-question .feedback")
    assert feedback.startswith("Right.") and len(feedback) > 60, feedback  # with its explanation


def test_lessons_cover_the_lecture():
    """Every topic of the lecture is a lesson (the ids the page's addresses use)."""
    assert LESSON_IDS == [
        "raytree-stop",
        "phong",
        "bounces",
        "sampling",
        "aliasing",
        "temporal",
        "motion",
        "glossy",
        "shadows",
        "dof",
        "integrators",
        "noise",
        "radiosity",
        "texture",
        "bump",
        "fog",
        "etched-glass",
    ]


def panels_state(page) -> tuple[list[str], list[str], list[str]]:
    """Every panel of the open lesson done and its picture loaded: their pictures' fingerprints, their jobs
    and the notes saying what each changed."""
    statuses = [p.get_attribute("data-status") for p in page.locator(".lesson-panel").all()]
    assert statuses == ["done"] * len(statuses), statuses
    pictures_loaded(page)
    jobs = [p.get_attribute("data-job") for p in page.locator(".lesson-panel").all()]
    return fingerprints(page), jobs, panel_texts(page, ".panel-notes")


def control_change_checked(page, lesson: str, at_first=None) -> None:
    """The open lesson's panels done, each saying what it cost; (`at_first()`, a lesson's own checks of these
    pictures;) its first control changed: the panels it touches render again into different pictures saying what
    changed, the others stay as they were."""
    before, jobs, notes = panels_state(page)
    costs = panel_texts(page, ".panel-info")
    assert all(re.match(r"[\d,]+ rays: .*[\d,]+ eye", c) and c.endswith(" s") for c in costs), costs
    if at_first is not None:
        at_first()

    touched = change_control(page, lesson)
    page.wait_for_function(
        f"""(old) => {{
            const ps = [...document.querySelectorAll('.lesson-panel')];
            return {touched}.every(i => ps[i].dataset.job !== old[i] && (p => {ENDED})(ps[i]));
        }}""",
        arg=jobs,
        timeout=120_000,
    )
    after, new_jobs, new_notes = panels_state(page)
    for i in range(len(before)):
        if i in touched:
            assert after[i] != before[i], f"panel {i} looks the same after the change"
            assert new_notes[i] != notes[i], "the panel does not say what changed"
        else:
            assert (after[i], new_jobs[i]) == (before[i], jobs[i]), f"panel {i} was rendered again"


# the noise lesson's control change is checked by test_lesson_noise_errors_against_the_references, around its own
# checks of the first pictures: its eight panels (two path-traced references) rendered once for both
@pytest.mark.parametrize("lesson", [lesson for lesson in LESSON_IDS if lesson != "noise"])
def test_lesson_control_changes_the_pictures_and_the_question_is_checked(desktop, lesson):
    page = desktop.open("#lessons").page
    assert page.locator(".lesson-button").count() == len(LESSON_IDS)
    open_lesson(page, lesson)
    control_change_checked(page, lesson)
    answer_question(page)
    desktop.shot(f"lesson-{lesson}", full_page=True)


def test_lesson_superseded_jobs_are_cancelled(desktop, server):
    """Moving a slider while the panels render cancels the jobs the new values replace."""
    desktop.allow.append(r"status of 409 \(Conflict\)")  # a job that ended just before its cancel came: 409
    page = desktop.open("#lessons").page
    page.click(".lesson-button[data-lesson=fog]")
    page.wait_for_function("() => document.querySelectorAll('.lesson-panel[data-job]').length === 2")
    first = page.get_attribute(".lesson-panel >> nth=1", "data-job")
    page.locator(".lesson-controls [data-key=density]").fill("0.2")
    page.wait_for_function(
        "(old) => { const p = document.querySelectorAll('.lesson-panel')[1]; "
        "return p.dataset.job !== old && p.dataset.status === 'done'; }",
        arg=first,
        timeout=120_000,
    )
    old = httpx.get(f"{server.url}/api/jobs/{first}", headers=TEACHER, timeout=30).json()
    assert old["status"] in ("cancelled", "done")  # done: it ended before the cancel came
    assert "fog.density = 0.2" in page.inner_text(".lesson-panel >> nth=1")


def test_lesson_circle_of_confusion_of_a_clicked_point(desktop):
    page = desktop.open("#lessons").page
    open_lesson(page, "dof")
    pictures_loaded(page)
    box = page.locator(".lesson-panel >> nth=0").locator("img.lesson-picture").bounding_box()
    # the near red ball (the lens focuses on the green ball, behind it)
    page.mouse.click(box["x"] + box["width"] * 0.58, box["y"] + box["height"] * 0.64)
    page.wait_for_selector(".coc-text[data-diameter]")
    text = page.inner_text(".coc-text")
    near = float(page.get_attribute(".coc-text", "data-diameter"))
    assert "near (red)" in text and near > 2, text
    assert page.get_attribute(".lesson-panel >> nth=1 >> canvas.lesson-overlay", "data-diameter") == f"{near:.2f}"
    # the magnifiers the pointer opened would cover the circle just drawn: hidden while the pointer stays on the
    # clicked picture, back once it has left it
    lenses = ".lesson-panel .inspect-lens:not([hidden])"
    page.mouse.move(box["x"] + box["width"] * 0.58 + 3, box["y"] + box["height"] * 0.64 + 2)
    assert page.locator(lenses).count() == 0
    desktop.shot("lesson-dof-coc-after-click")
    page.mouse.move(box["x"] + box["width"] * 0.5, box["y"] - 20)
    page.mouse.move(box["x"] + box["width"] * 0.3, box["y"] + box["height"] * 0.3)
    page.wait_for_function(f"() => document.querySelectorAll('{lenses}').length === 2")
    # the green ball, near the focal plane: a smaller circle
    page.mouse.click(box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.47)
    page.wait_for_function("(d) => document.querySelector('.coc-text').dataset.diameter !== d", arg=f"{near:.2f}")
    text = page.inner_text(".coc-text")
    assert "in focus (green)" in text and float(page.get_attribute(".coc-text", "data-diameter")) < 1 < near, text
    desktop.shot("lesson-dof-coc", full_page=True)
    # the keyboard does what the click does: the arrows move the lens (from the middle), Space clicks there
    picture = page.locator(".lesson-panel >> nth=0").locator("img.lesson-picture")
    w, h = picture.evaluate("i => [i.naturalWidth, i.naturalHeight]")
    picture.focus()
    page.keyboard.press("ArrowLeft")
    page.keyboard.press(" ")
    page.wait_for_function("(p) => document.querySelector('.coc-text').textContent.startsWith(p)",
                           arg=f"Pixel ({w // 2 - 1}, {h // 2})")  # fmt: skip


def test_lesson_radiosity_two_pass_shadows_are_clean(desktop, server):
    """The question asks why two-pass has the sharper shadows: its panel must not hide them in noise. Its RMS
    difference from the same scene at 64 rays per pixel and 16 shadow rays each (the same seed, so the same
    radiosity solution: what differs is the per-pixel noise) stays under 2 levels of 255; with 4 rays per pixel
    and 2 shadow rays it was 4.1, speckles plain to see, where the flat and smooth panels have none."""
    page = desktop.open("#lessons").page
    open_lesson(page, "radiosity")
    pictures_loaded(page)
    job = page.get_attribute(".lesson-panel >> nth=2", "data-job")
    with httpx.Client(base_url=server.url, headers=TEACHER, timeout=30) as client:
        scene = client.get(f"/api/jobs/{job}/scene").json()
        assert scene["render"]["radiosity"]["display"] == "two-pass"
        scene["sampler"]["spp"] = 64
        scene["render"]["light_samples"] = 16
        r = client.post("/api/jobs", json={"scene": scene})
        assert r.status_code == 202, r.text
        reference = wait_finished(client, r.json()["id"], timeout=120)
    assert reference["status"] == "done", reference
    rms = float(np.sqrt(((job_png(server, job) - job_png(server, reference["id"])) ** 2).mean()))
    assert rms < 2.0, rms


def test_lesson_ray_tree_question_is_about_the_left_picture(desktop):
    """The ray tree question's max_depth is where the left picture's slider starts, its pixel is marked on that
    picture, and the explanation sends the student to a picture cut at that depth."""
    page = desktop.open("#lessons").page
    page.click(".lesson-button[data-lesson=raytree-stop]")
    page.wait_for_selector(".lesson-question .choice", timeout=60_000)
    depth = int(re.search(r"max_depth (\d+)", page.inner_text(".lesson-question .question"))[1])
    assert int(page.input_value(".lesson-controls [data-key=depth]")) == depth
    panels = page.locator(".lesson-panel")
    assert panels.nth(0).locator(".lesson-mark").count() == 1
    answer_question(page)
    feedback = page.inner_text(".lesson-question .feedback")
    side = re.search(r"[Tt]he (left|right) picture is cut at depth (\d+)", feedback)
    assert side and int(side[2]) == depth, feedback
    assert f"render.max_depth = {depth}" in panels.nth(["left", "right"].index(side[1])).inner_text()


def test_lesson_motion_words_name_every_moving_object(desktop, server):
    """What moves in the moving picture's scene (its objects with a velocity, as the server rendered them) is what
    the lesson's words name: each as its material and kind ("red ball") in the text, the control and the answers."""
    page = desktop.open("#lessons").page
    open_lesson(page, "motion")
    job = page.get_attribute(".lesson-panel >> nth=1", "data-job")
    scene = httpx.get(f"{server.url}/api/jobs/{job}/scene", headers=TEACHER, timeout=30).json()
    moving = [o for o in scene["objects"] if any(o.get("velocity") or [])]
    assert moving, "nothing moves in the moving picture"
    words = {
        "text": page.inner_text(".lesson-text"),
        "control": page.inner_text(".lesson-controls"),
        "question": page.inner_text(".lesson-question .choices"),
    }
    for o in moving:
        name = f"{o['material']} {o['name'].split()[-1]}"  # "red ball"
        assert all(name in w for w in words.values()), (name, words)


def test_lesson_texts_link_to_the_reference_sections_they_name(desktop, server):
    """Every lesson links to the reference that explains what its text only names (the server's /reference/
    pages, which work offline): each link's page is served and has the section its anchor names. The links are
    shown under the lesson's text."""
    page = desktop.open("#lessons").page
    more = page.evaluate(
        "async () => (await import('/js/lessons.js')).LESSONS.map(l => [l.id, (l.more || []).map(([, href]) => href)])"
    )
    assert [i for i, hrefs in more if not hrefs] == [], "lessons without a link to the reference"
    pages: dict[str, str] = {}
    for href in sorted({h for _, hrefs in more for h in hrefs}):
        path, _, anchor = href.partition("#")
        assert path.startswith("/reference/") and anchor, href
        if path not in pages:
            r = httpx.get(f"{server.url}{path}", timeout=30)
            assert r.status_code == 200, (href, r.status_code)
            pages[path] = r.text
        assert f'id="{anchor}"' in pages[path], f"{path} has no section #{anchor}"
    open_lesson(page, "fog")
    shown = [a.get_attribute("href") for a in page.locator("#lesson-stage .lesson-more a").all()]
    assert shown == dict(more)["fog"]


def test_lesson_phong_captions_one_change_a_line(desktop):
    """Under each Phong picture, what changed is one change a line, and no field is named twice (the ambient
    picture said "kd = 0.7 × blue" and then "kd = ks = 0", run together on one line): the kd, ks and n sliders
    change only the pictures that have their term."""
    page = desktop.open("#lessons").page
    open_lesson(page, "phong")
    for i, panel in enumerate(page.locator(".lesson-panel").all()):
        items = panel.locator(".panel-notes li")
        notes = items.all_inner_texts()
        assert len(notes) >= 2, (i, notes)
        fields = [f.strip() for n in notes for f in n.split(" = ")[:-1]]  # "kd = ks = 0": kd and ks
        assert len(fields) == len(set(fields)), (i, notes)
        tops = [items.nth(k).bounding_box()["y"] for k in range(len(notes))]
        assert tops == sorted(set(tops)), (i, notes, tops)  # each on a line of its own
    assert page.locator(".lesson-panel >> nth=0").locator(".panel-notes").inner_text().splitlines() == [
        "ka = 0.3",
        "kd = ks = 0 everywhere (each ka kept)",
    ]
    desktop.shot("lesson-phong-captions")


def test_lesson_radiosity_links_to_the_shooting_view(desktop):
    page = desktop.open("#lessons").page
    open_lesson(page, "radiosity")
    page.locator(".lesson-panel >> nth=2").get_by_role("button", name="Step through the shooting").click()
    page.wait_for_selector("#page-work:not([hidden]) #radiosity:not([hidden]) #rad-body:not([hidden])")
    assert page.locator("#rad-step").get_attribute("max") not in (None, "0")


def test_lesson_mystery_pictures_are_named_once_answered(desktop):
    page = desktop.open("#lessons").page
    open_lesson(page, "aliasing")
    titles = panel_texts(page, "figcaption strong")
    assert titles[2:] == ["picture A", "picture B"]
    assert panel_texts(page, ".panel-notes")[3] == ""  # what B changed would give it away
    page.wait_for_function(
        "() => [...document.querySelectorAll('img.rays-map')].every(i => i.complete && i.naturalWidth)"
    )
    answer_question(page)
    titles = panel_texts(page, "figcaption strong")
    assert titles[3].startswith("picture B: adaptive")


def panel_errors(page) -> list[float | None]:
    """Each panel's RMS difference from its reference (levels of 255), as written under it; None: no error shown."""
    return page.evaluate(
        """() => [...document.querySelectorAll('.lesson-panel')].map(p => {
            const e = p.querySelector('.panel-error');
            return e && e.dataset.rms ? Number(e.dataset.rms) : null;
        })"""
    )


def wait_for_errors(page, n: int) -> None:
    page.wait_for_function(
        "(n) => document.querySelectorAll('.lesson-panel .panel-error[data-rms]').length === n", arg=n, timeout=60_000
    )


def test_lesson_noise_errors_against_the_references(desktop, server):
    """The noise lesson: random, jittered and low-discrepancy at the same rays per pixel, on the checkered floor
    (top row) and on the path-traced Cornell box (bottom row), each with its RMS difference from its row's
    reference. On the floor the film position is all that is sampled: low-discrepancy < jittered < random. In
    the box the noise comes from the bounces, which the sampler does not choose: the three are within 10 %.
    The page's numbers are checked against the PNGs themselves; the drawings say how evenly the points lie. Its
    control's change (to 4 rays) and its question are checked as every lesson's are, around the first pictures'
    checks; then 64 rays."""
    page = desktop.open("#lessons").page
    assert page.locator(".lesson-button").count() == len(LESSON_IDS)
    open_lesson(page, "noise")
    errors: list[float | None] = []

    def first_pictures() -> None:
        wait_for_errors(page, 6)
        errors[:] = panel_errors(page)
        assert errors[3] is None and errors[7] is None, errors  # the references
        floor, box = errors[0:3], errors[4:7]
        assert floor[2] < floor[1] < floor[0] and floor[2] < 0.7 * floor[0], floor
        assert max(box) < 1.1 * min(box), box

        # the numbers are the RMS difference of the pictures' own PNGs (0-255, over the three channels)
        jobs = [p.get_attribute("data-job") for p in page.locator(".lesson-panel").all()]
        for i, ref in ((0, 3), (2, 3), (5, 7)):
            rms = float(np.sqrt(((job_png(server, jobs[i]) - job_png(server, jobs[ref])) ** 2).mean()))
            assert abs(rms - errors[i]) < 0.01, (i, rms, errors[i])

        # one pixel's points: the low-discrepancy ones fill every cell, column and row; random ones leave gaps
        page.wait_for_function("() => [...document.querySelectorAll('canvas.samples')].every(c => c.dataset.positions)")
        words = panel_texts(page, ".samples-box small")
        assert len(words) == 6, words
        assert "One in each of the 4 × 4 cells, 16 columns and 16 rows" in words[2], words[2]
        assert "Empty: 0 of the 4 × 4 cells" in words[1], words[1]
        assert re.search(r"Empty: [1-9]\d* of the 4 × 4 cells", words[0]), words[0]

    control_change_checked(page, "noise", first_pictures)
    answer_question(page)
    desktop.shot("lesson-noise", full_page=True)

    # more rays: every error falls (against the first pictures' 16)
    page.locator(".lesson-controls [data-key=spp]").select_option("64")
    page.wait_for_function(
        """() => [...document.querySelectorAll('.lesson-panel')].every(p => p.dataset.status === 'done')
            && [...document.querySelectorAll('.lesson-panel code')]
                .filter(c => c.textContent.includes('sampler.spp = 64')).length === 6""",
        timeout=120_000,
    )
    pictures_loaded(page)
    wait_for_errors(page, 6)
    more = panel_errors(page)
    assert all(more[i] < errors[i] for i in (0, 1, 2, 4, 5, 6)), (errors, more)
    assert more[2] < more[1] < more[0], more
    desktop.shot("lesson-noise-64", full_page=True)


def job_scene(server, page, panel: int) -> dict:
    job = page.get_attribute(f".lesson-panel >> nth={panel}", "data-job")
    return httpx.get(f"{server.url}/api/jobs/{job}/scene", headers=TEACHER, timeout=30).json()


def test_lesson_shadows_one_box_only_the_light_changes(desktop, server):
    """The three shadow pictures are one scene: the left one's square ceiling light is a point light at its
    centre (as bright straight down), the right two differ only in their shadow rays per point."""
    page = desktop.open("#lessons").page
    open_lesson(page, "shadows")
    pictures_loaded(page)
    scenes = [job_scene(server, page, i) for i in range(3)]
    lights = [s.pop("lights") for s in scenes]
    samples = [s["render"].pop("light_samples", None) for s in scenes]
    assert scenes[0] == scenes[1] == scenes[2], "the pictures are of different scenes"
    assert lights[1] == lights[2]
    assert [light["type"] for light in lights[1]] == ["quad"]
    (quad,), (point,) = lights[1], lights[0]
    centre = np.add(quad["corner"], np.add(quad["edge1"], quad["edge2"]) / 2)
    assert point["type"] == "point" and np.allclose(point["position"], centre - [0, 0.01, 0])
    area = np.linalg.norm(np.cross(quad["edge1"], quad["edge2"]))
    assert np.allclose(point["intensity"], np.multiply(quad["radiance"], area))  # radiance * area, straight down
    assert samples[1] == 1
    assert samples[2] == 16
    floor = [job_png(server, page.get_attribute(f".lesson-panel >> nth={i}", "data-job"))[-12:, 50:70].mean()
             for i in range(3)]  # fmt: skip
    assert abs(floor[0] - floor[2]) < 0.15 * floor[2], floor  # the floor under the light: lit alike
    desktop.shot("lesson-shadows-one-box", full_page=True)


def test_lesson_phong_ambient_only_has_no_light_anywhere(desktop, server):
    """The ambient picture shows ka·Ia alone: every surface is one flat colour (no lit floor, no cast shadow)."""
    page = desktop.open("#lessons").page
    open_lesson(page, "phong")
    pictures_loaded(page)
    scene = job_scene(server, page, 0)
    assert all(m.get("kd") == 0 and m.get("ks", 0) == 0 and "ka" in m for m in scene["materials"].values())
    png = job_png(server, page.get_attribute(".lesson-panel >> nth=0", "data-job"))
    lit = job_png(server, page.get_attribute(".lesson-panel >> nth=1", "data-job"))
    rows = slice(png.shape[0] - 20, png.shape[0])  # the floor in front of the ball: flat, where light varies
    assert np.ptp(png[rows], axis=(0, 1)).max() <= 2, np.ptp(png[rows], axis=(0, 1))
    assert np.ptp(lit[rows], axis=(0, 1)).max() > 10  # the diffuse picture's floor is lit (it would fail the above)
    desktop.shot("lesson-phong-ambient-only", full_page=True)


def test_lesson_ray_tree_pixel_is_marked_in_the_workspace(desktop):
    """ "Open it in the workspace and click the marked pixel": the workspace's picture marks the question's pixel
    (the keyboard's cursor starts there: Enter shows its tree)."""
    page = desktop.open("#lessons").page
    page.click(".lesson-button[data-lesson=raytree-stop]")
    page.wait_for_selector(".lesson-panel >> nth=0 >> .lesson-mark", timeout=60_000)
    mark = page.locator(".lesson-panel >> nth=0 >> .lesson-mark")
    x, y = int(mark.get_attribute("data-x")), int(mark.get_attribute("data-y"))
    open_lesson(page, "raytree-stop")
    page.locator(".lesson-panel >> nth=0").get_by_role("button", name="Open in workspace").click()
    page.wait_for_selector("#page-work:not([hidden]) #stage-marker[data-kind=lesson]:not([hidden])")
    page.wait_for_function("() => document.querySelector('#render-img').complete")
    at = page.evaluate(
        """() => { const m = document.querySelector('#stage-marker').getBoundingClientRect();
                   const i = document.querySelector('#render-img').getBoundingClientRect();
                   const w = document.querySelector('#render-img').naturalWidth;
                   const h = document.querySelector('#render-img').naturalHeight;
                   return [Math.floor((m.left + m.width / 2 - i.left) / i.width * w),
                           Math.floor((m.top + m.height / 2 - i.top) / i.height * h),
                           m.top >= 0 && m.bottom <= innerHeight]; }"""
    )
    assert at == [x, y, True], at
    assert f"pixel ({x}, {y}) is marked" in page.inner_text("#viewer-message")
    desktop.shot("lesson-raytree-marked-in-workspace")
    page.focus("#render-img")
    page.keyboard.press("Enter")
    page.wait_for_function(f"() => document.querySelector('#rt-pixel').textContent === 'pixel ({x}, {y})'")
    page.wait_for_selector("#rt-diagram .rt-node")
    assert page.get_attribute("#stage-marker", "data-kind") is None  # picked: the usual marker


def test_lesson_on_a_phone_comes_before_the_list_and_its_tree_is_readable(phone):
    page = phone.open("#lessons/raytree-stop").page
    page.wait_for_selector(".lesson-panel >> nth=0 >> .lesson-mark", timeout=90_000)
    tops = page.evaluate(
        """() => ['#lesson-stage', '.lesson-nav', '#lesson-stage h2']
            .map((s) => document.querySelector(s).getBoundingClientRect().top)"""
    )
    assert tops[0] < tops[1] and tops[2] < PHONE["height"], tops  # the lesson, its title in view; the list under it
    phone.shot("lesson-phone-first")
    page.wait_for_function(
        "() => [...document.querySelectorAll('.lesson-panel')].every(p => p.dataset.status === 'done')", timeout=90_000
    )
    page.locator(".lesson-panel >> nth=0").get_by_role("button", name="Open in workspace").click()
    page.wait_for_selector("#stage-marker[data-kind=lesson]:not([hidden])")
    page.focus("#render-img")
    page.keyboard.press("Enter")
    page.wait_for_selector("#rt-diagram .rt-node")
    assert page.get_attribute("#rt-fit", "aria-pressed") == "false"
    seen = page.evaluate(
        """() => { const d = document.querySelector('#rt-diagram');
                   const t = d.querySelector('.rt-node text').getBoundingClientRect();
                   return { scale: d.dataset.scale, text: t.height, scrolls: d.scrollWidth > d.clientWidth,
                            page: document.documentElement.scrollWidth }; }"""
    )
    assert seen["scale"] == "1" and seen["text"] >= 10 and seen["page"] <= PHONE["width"], seen
    page.locator("#rt-diagram").scroll_into_view_if_needed()
    phone.shot("lesson-phone-raytree")


def in_view(page, selector: str) -> bool:
    return page.evaluate(
        """(s) => { const r = document.querySelector(s).getBoundingClientRect();
                    return r.height > 0 && r.top >= 0 && r.bottom <= innerHeight; }""",
        selector,
    )


def test_lesson_answer_in_view_marked_done_and_next(desktop):
    """The Check's answer is brought into view (it appeared below the fold with nothing in view changing) in a live
    region; a lesson answered right is marked done in the list (kept in localStorage: there after a reload); a
    "Next lesson" button opens the next one at its own address (issue #42)."""
    first, second = LESSON_IDS[0], LESSON_IDS[1]
    page = desktop.open(f"#lessons/{first}").page
    page.wait_for_selector(".lesson-question .choice", timeout=90_000)
    # the panels' pictures done first: a panel that ends moves what is under it by a line (its progress bar gives way
    # to what the render cost, a comparison's error), which could take the button out of view after the scroll
    panels_ended(page, first)
    assert page.locator(".lesson-done:visible").count() == 0  # nothing done yet
    answer = page.evaluate("() => document.querySelector('.lesson-question').question.answer")
    wrong = f".lesson-question .choice[data-choice='{(answer + 1) % page.locator('.lesson-question .choice').count()}']"
    feedback = ".lesson-question .feedback"
    assert page.get_attribute(feedback, "aria-live") == "polite"
    assert page.get_attribute(feedback, "role") == "status"
    page.eval_on_selector(wrong, "b => b.scrollIntoView({ block: 'end' })")  # the answers at the foot of the window
    page.click(wrong)
    assert page.get_attribute(feedback, "data-verdict") == "wrong" and in_view(page, feedback)
    assert page.locator(".lesson-done:visible").count() == 0
    right = f".lesson-question .choice[data-choice='{answer}']"
    page.eval_on_selector(right, "b => b.scrollIntoView({ block: 'end' })")
    page.click(right)
    assert page.get_attribute(feedback, "data-verdict") == "right" and in_view(page, feedback)
    assert in_view(page, "#lesson-next")
    assert page.locator(f".lesson-button[data-lesson={first}] .lesson-done").is_visible()
    assert "(done)" in page.inner_text(f".lesson-button[data-lesson={first}]")
    assert page.evaluate("() => JSON.parse(localStorage.getItem('rt.lessons.done'))") == [first]
    desktop.shot("lesson-answered-next")
    title = page.inner_text(f".lesson-button[data-lesson={second}]")
    assert page.inner_text("#lesson-next") == f"Next lesson: {title} \u2192"
    page.click("#lesson-next")
    page.wait_for_function(f"() => document.querySelector('#lesson-stage').dataset.lesson === '{second}'")
    assert page.evaluate("() => location.hash") == f"#lessons/{second}"
    assert page.get_attribute(f".lesson-button[data-lesson={second}]", "aria-current") == "true"
    page.reload()
    page.wait_for_selector(f".lesson-button[data-lesson={first}]")
    assert page.locator(f".lesson-button[data-lesson={first}] .lesson-done").is_visible()
    assert not page.locator(f".lesson-button[data-lesson={second}] .lesson-done").is_visible()


def test_lesson_on_a_phone_switches_without_scrolling_past_the_lesson(phone):
    """On a phone the lesson comes first (its list under it): a menu above the lesson's title switches lessons, so
    no one scrolls past the whole lesson to reach the list (issue #42)."""
    page = phone.open(f"#lessons/{LESSON_IDS[1]}").page
    page.wait_for_selector("#lesson-switch")
    assert in_view(page, "#lesson-switch") and in_view(page, "#lesson-stage h2")
    assert page.input_value("#lesson-switch") == LESSON_IDS[1]
    phone.shot("lesson-phone-switch")
    page.select_option("#lesson-switch", LESSON_IDS[2])
    page.wait_for_function(f"() => document.querySelector('#lesson-stage').dataset.lesson === '{LESSON_IDS[2]}'")
    assert page.evaluate("() => location.hash") == f"#lessons/{LESSON_IDS[2]}"
    assert in_view(page, "#lesson-stage h2") and page.input_value("#lesson-switch") == LESSON_IDS[2]
    page.wait_for_selector(".lesson-question .choice", timeout=90_000)


# each panel's height whenever its status changes, kept on the panel (set before the lesson opens)
WATCH_HEIGHTS = """() => new MutationObserver((changes) => {
    for (const c of changes) {
        const p = c.target;
        if (!p.classList?.contains('lesson-panel')) continue;
        (p.heights ||= []).push([p.dataset.status, p.querySelector('.panel-info').textContent,
                                 p.getBoundingClientRect().height]);
    }
}).observe(document.querySelector('#lesson-stage'),
            {subtree: true, attributes: true, attributeFilter: ['data-status']})"""


def test_lesson_a_panel_keeps_its_height_when_its_render_ends(desktop):
    """A panel's render ending moves nothing under it (the question, "Next lesson"): its progress bar lies along the
    picture's foot, and the line of what the render cost is there while it runs, its numbers counting up. (A lesson
    without a comparison: a comparison's error line changes its words when both pictures are known.)"""
    lesson = "raytree-stop"
    assert lesson in LESSON_IDS
    page = desktop.open("#lessons").page
    page.evaluate(WATCH_HEIGHTS)
    open_lesson(page, lesson)
    seen = page.eval_on_selector_all(".lesson-panel", "ps => ps.map(p => p.heights || [])")
    measured = 0
    for heights in seen:
        running = [h for h in heights if h[0] == "running"]
        done = [h for h in heights if h[0] == "done"]
        if not running or not done:
            continue  # answered at once (a render the server had): nothing ran
        measured += 1
        assert running[-1][1].endswith(" s"), f"no cost line while it ran: {heights}"
        assert abs(done[-1][2] - running[-1][2]) <= 1, heights
    assert measured >= 1, seen
