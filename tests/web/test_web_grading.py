"""The instructor's grading view (the page's "Grading" tab, web/js/grading.js) in a real browser.

Uses the fixtures of tests/web/conftest.py: `python -m server` on loopback with one render worker and an
instructor token (typed into the tab, as an instructor would), Debian's Chromium driven by Playwright,
and a page that fails on console errors it did not expect. The example
class (scenes/grading/class, 9 students) is graded through the page; on this 2-core machine that takes
15 to 30 s, so the waits are generous. Screenshots of the done table and of erin's detail, at 1280 x 800
and 390 x 844, go to /tmp/grading-*.png for a person to look at.
"""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import httpx

from tests.support.api import INSTRUCTOR, long_scene, wait_for
from tests.support.grading_page import enter_token, load_example
from tests.support.page import PHONE, TEACHER, Page
from tests.support.scene import ROOT

GRADE_TIMEOUT = 240_000  # ms: the whole class, renders and metrics
SHOT_DIR = Path("/tmp")
EXPECTED = {  # the example class as the API grades it: score / max (percent) (status)
    "alice": ("13 / 13 (100 %)", "graded"),
    "bob": ("6 / 13 (46.2 %)", "graded"),
    "carol": ("0 / 13 (0 %)", "invalid"),
    "dave": ("13 / 13 (100 %)", "graded"),
    "erin": ("7 / 13 (53.8 %)", "graded"),
    "frank": ("0 / 13 (0 %)", "invalid"),
    "grace": ("7 / 7 (100 %)", "graded"),
    "heidi": ("1 / 7 (14.3 %)", "graded"),
    "ivan": ("0 / 7 (0 %)", "invalid"),
}
PICTURES = ("render", "reference", "error_map", "rejected")


def shot(page, name: str, full_page: bool = False) -> None:
    page.screenshot(path=str(SHOT_DIR / f"grading-{name}.png"), full_page=full_page)


def open_grading(p: Page, token: str | None = INSTRUCTOR):
    """The Grading tab, the instructor's token typed into its field (unless None)."""
    page = p.open().page
    page.click("#tab-grading")
    assert page.get_attribute("#tab-grading", "aria-selected") == "true"
    assert page.is_visible("#page-grading")
    assert not page.is_visible("#page-work")
    assert page.evaluate("() => location.hash") == "#grading"
    if token is not None:
        enter_token(page, token)
    return page


def table_rows(page) -> dict[str, tuple[str, str]]:
    return page.evaluate(
        """() => Object.fromEntries([...document.querySelectorAll('#grade-table tbody tr')].map(tr => [
            tr.dataset.student,
            [tr.querySelector('td.score').textContent.trim(), tr.dataset.status]]))"""
    )


def row_order(page) -> list[str]:
    return page.evaluate("() => [...document.querySelectorAll('#grade-table tbody tr')].map(tr => tr.dataset.student)")


def wait_pictures(page, n: int = 4) -> None:
    page.wait_for_function(
        f"""() => {{
            const imgs = [...document.querySelectorAll('#grade-detail .grade-fig img')];
            return imgs.length === {n} && imgs.every(i => i.complete && i.naturalWidth > 0);
        }}"""
    )


def grade_example_over_api(server) -> str:
    """Grade the example class without the page; the run's id once it is done."""
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        example = c.get("/api/grade/example").json()
        r = c.post("/api/grade", json={"assignment": example["assignment"], "submissions": example["submissions"]})
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        wait_for(
            lambda: c.get(f"/api/grade/{run_id}").json()["status"] in ("done", "failed"),
            GRADE_TIMEOUT / 1000,
            "the example class graded",
            interval=0.5,
        )
        state = c.get(f"/api/grade/{run_id}").json()
        assert state["status"] == "done", state.get("error")
        return run_id


# --------------------------------------------------------------------------------------------------


def test_web_grading_example_class_table_and_erins_detail(desktop, server):
    page = open_grading(desktop)
    load_example(page)
    kinds = dict(
        page.eval_on_selector_all("#grade-sub-rows tr", "trs => trs.map(r => [r.dataset.student, r.dataset.kind])")
    )
    assert kinds == {**{s: "scene" for s in ("alice", "bob", "carol", "dave", "erin", "frank")},
                     "grace": "png", "heidi": "exr", "ivan": "png"}  # fmt: skip

    # the status line while it runs: "renders 3/7"
    page.evaluate(
        """() => {
            window.__statuses = [];
            const el = document.querySelector('#grade-status');
            new MutationObserver(() => window.__statuses.push(el.textContent))
                .observe(el, {childList: true, characterData: true, subtree: true});
        }"""
    )
    # a long job holds the only worker, so the class's renders wait where the page can see them
    busy = httpx.post(f"{server.url}/api/jobs", json={"scene": long_scene()}, headers=TEACHER, timeout=30).json()["id"]
    job_url = f"{server.url}/api/jobs/{busy}"
    wait_for(lambda: httpx.get(job_url, headers=TEACHER, timeout=30).json()["status"] == "running", 60, "the long job")
    page.click("#grade-start")
    try:
        page.wait_for_function(r"() => window.__statuses.some(s => /renders \d+\/\d+/.test(s))", timeout=GRADE_TIMEOUT)
    finally:
        httpx.delete(job_url, headers=TEACHER, timeout=30)
    page.wait_for_selector("#grade-table", timeout=GRADE_TIMEOUT)
    statuses = page.evaluate("() => window.__statuses")
    assert any(re.search(r"renders \d+/\d+", s) for s in statuses), statuses
    assert page.text_content("#grade-status").startswith("Graded 9 students")
    assert page.get_attribute("#page-grading", "data-status") == "done"

    # the table: one row per student, the exact scores the API gives
    assert table_rows(page) == {k: list(v) for k, v in EXPECTED.items()}
    stats = dict(
        page.eval_on_selector_all(
            "#grade-stats [data-stat]", "ds => ds.map(d => [d.dataset.stat, d.lastChild.textContent])"
        )
    )
    assert stats == {  # in percent: scenes are out of 13 points, images out of 7
        "students": "9",
        "mean": "46 %",
        "min": "0 %",
        "max": "100 %",
        "out-of": "13 (scene) · 7 (image)",  # an image earns its readability's and the image tests' points
        "graded": "6",
        "invalid": "3",
        "failed": "0",
    }
    headers = page.eval_on_selector_all("#grade-table thead th.test", "ths => ths.map(th => th.dataset.test)")
    assert headers[:2] == ["valid scene", "readable image"]
    assert "FLIP against the reference" in headers
    assert len(headers) == 11
    flip = page.locator('#grade-table tr[data-student=erin] td[data-test="FLIP against the reference"]')
    assert flip.get_attribute("data-status") == "failed"
    title = flip.get_attribute("title")  # the output as a tooltip
    assert title.startswith("Differs from the reference more than noise can explain: FLIP 0.07")
    assert "✗" in flip.text_content()
    glass = page.locator('#grade-table tr[data-student=erin] td[data-test="a glass object"]')
    assert glass.get_attribute("data-status") == "passed"
    assert "✓" in glass.text_content()
    grace = page.locator("#grade-table tr[data-student=grace] td.test").first  # scenes' tests: not for an image
    assert grace.get_attribute("class") == "test na"
    assert grace.text_content().startswith("·")
    assert page.text_content("#grade-table tr[data-student=erin] td[data-metric=rejected]").strip() == "12.72 %"

    # the summary links
    run_id = page.evaluate("() => JSON.parse(localStorage.getItem('grading.run'))")
    csv_href = page.get_attribute("#grade-csv", "href")
    assert csv_href == f"/api/grade/{run_id}/summary.csv"
    with page.expect_download() as caught:  # fetched with the instructor's token, saved from a blob
        page.click("#grade-csv")
    assert caught.value.suggested_filename == "summary.csv"
    csv = Path(caught.value.path()).read_text()
    assert csv == httpx.get(server.url + csv_href, headers=TEACHER).text
    assert csv.startswith("student,kind,status,score,max_score")
    assert "\nerin,scene,graded,7.0,13.0," in csv
    assert httpx.get(server.url + csv_href).status_code == 401  # not without the token
    with page.context.expect_page() as opened:  # summary.json opens in a new tab
        page.click("#grade-json")
    tab = opened.value
    tab.wait_for_load_state()
    assert tab.url.startswith("blob:") and re.search(r'"students":\s*9', tab.content())
    tab.close()
    summary = httpx.get(server.url + page.get_attribute("#grade-json", "href"), headers=TEACHER).json()
    assert summary["statistics"]["students"] == 9

    # sorting: by score (best first, as a fraction of the maximum), then back by name
    page.click("#grade-table th[data-col=score] button")
    order = row_order(page)
    assert set(order[:3]) == {"alice", "dave", "grace"}
    assert set(order[-3:]) == {"carol", "frank", "ivan"}
    assert page.get_attribute("#grade-table th[data-col=score]", "aria-sort") == "descending"
    page.click("#grade-table th[data-col=student] button")
    assert row_order(page) == sorted(EXPECTED)
    page.locator("#grade-results").scroll_into_view_if_needed()
    shot(page, "desktop-table")
    # 1280 px wide: the whole table is in its box, the last column (rejected) included, no sideways scrolling
    assert page.viewport_size["width"] == 1280
    fit = page.evaluate(
        """() => { const b = document.querySelector('.grade-table-box');
            const last = document.querySelector('#grade-table thead th:last-child').getBoundingClientRect();
            return [b.scrollWidth, b.clientWidth, last.right, b.getBoundingClientRect().right]; }"""
    )
    assert fit[0] <= fit[1] and fit[2] <= fit[3], fit

    # erin's detail, from the keyboard: focus the row, Enter
    page.focus("#grade-table tr[data-student=erin]")
    page.keyboard.press("Enter")
    page.wait_for_selector("#grade-detail:not([hidden])")
    assert page.text_content("#h-grade-detail") == "erin"
    assert page.evaluate("() => document.activeElement.id") == "h-grade-detail"
    assert page.get_attribute("#grade-table tr[data-student=erin]", "aria-current") == "true"
    wait_pictures(page)
    srcs = page.eval_on_selector_all("#grade-detail .grade-fig img", "imgs => imgs.map(i => i.dataset.src)")
    assert srcs == [f"/api/grade/{run_id}/students/erin/{p}.png" for p in PICTURES]  # shown as blob: URLs
    sizes = page.eval_on_selector_all(
        "#grade-detail .grade-fig img",
        "imgs => imgs.map(i => [i.naturalWidth, i.getBoundingClientRect().width, getComputedStyle(i).imageRendering])",
    )
    for natural, shown, rendering in sizes:
        assert natural == 96 and shown >= 2 * natural and rendering == "pixelated", sizes
    flip_test = page.locator('#grade-detail-tests li[data-test="FLIP against the reference"]')
    assert flip_test.get_attribute("data-status") == "failed"
    assert "failed" in flip_test.text_content()
    assert "0 / 2" in flip_test.text_content()
    assert "the noise baseline" in flip_test.text_content()
    caption = page.text_content("#grade-detail .grade-fig[data-picture=rejected] figcaption")
    assert caption.startswith("rejected pixels: red where they differ beyond noise")  # the grader's caption
    glass_out = page.text_content('#grade-detail-tests li[data-test="a glass object"] pre')  # multi-line: <pre>
    assert glass_out.startswith("passed: found 1 materials")
    assert "\n" in glass_out
    assert page.locator("#grade-detail-tests li").count() == 10
    links = page.eval_on_selector_all("#grade-detail a.button", "as => as.map(a => a.getAttribute('href'))")
    assert f"/api/grade/{run_id}/students/erin/results.json" in links
    assert f"/api/grade/{run_id}/students/erin/report.json" in links
    results = httpx.get(f"{server.url}/api/grade/{run_id}/students/erin/results.json", headers=TEACHER).json()
    assert results["score"] == 7.0
    page.wait_for_timeout(600)  # the smooth scroll to the detail ends
    page.evaluate("() => window.scrollTo(0, document.querySelector('#grade-detail').offsetTop - 8)")
    shot(page, "desktop-erin")

    # an invalid scene: its errors, no pictures; Close gives the focus back to the row
    page.click("#grade-table tr[data-student=frank]")
    page.wait_for_function("() => document.querySelector('#h-grade-detail').textContent === 'frank'")
    errors = page.text_content("#grade-detail-errors")
    assert "objects[1].radius" in errors
    assert "did you mean 'red'?" in errors
    assert page.locator("#grade-detail .grade-fig img").count() == 0
    page.click("#grade-detail-close")
    assert page.is_hidden("#grade-detail")
    assert page.evaluate("() => document.activeElement.dataset.student") == "frank"


def test_web_grading_broken_assignment_shows_the_servers_paths(desktop):
    desktop.allow.append(r"status of 422")  # Chromium logs the refused request
    page = open_grading(desktop)
    load_example(page)
    text = page.input_value("#grade-assignment")
    assert text.count('"check": "area_light"') == 1
    broken = text.replace('"check": "area_light"', '"check": "unicorn_light"')
    page.fill("#grade-assignment", broken)
    page.click("#grade-start")
    page.wait_for_selector("#grade-errors li.problem-item")
    item = page.locator("#grade-errors li.problem-item").first
    assert item.locator("code.where").text_content() == "assignment.requirements[1].check"
    assert "unknown preset 'unicorn_light'" in item.text_content()
    assert page.get_attribute("#grade-status", "data-kind") == "error"
    assert page.is_hidden("#grade-results")
    assert not page.is_disabled("#grade-start")
    # the item knows its line, and selects the value in the editor
    line = broken[: broken.index('"unicorn_light"')].count("\n") + 1
    button = item.locator("button")
    assert button.text_content() == f"line {line}"
    button.click()
    selected = page.eval_on_selector("#grade-assignment", "t => t.value.slice(t.selectionStart, t.selectionEnd)")
    assert selected == '"check": "unicorn_light"'
    assert page.evaluate("() => document.activeElement.id") == "grade-assignment"
    shot(page, "desktop-422")

    # a syntax error is found without asking the server, at its line and column
    page.fill("#grade-assignment", '{\n  "version": 1,\n  "name": "x",,\n}')
    page.click("#grade-start")
    first = page.locator("#grade-errors li.problem-item").first
    assert first.locator("code.where").text_content().startswith("line 3, column")
    # a body the server refuses (no submissions) is listed by the submissions
    page.fill("#grade-assignment", broken)
    page.click("#grade-clear")
    page.click("#grade-start")
    assert "add the submissions first" in page.text_content("#grade-sub-errors")


def test_web_grading_files_and_a_phone(phone, server, tmp_path):
    """Files picked (a scene, an image, a stray text file; then a zip alone), and the phone layout of
    the table and a student's detail (the run graded over the API, shown again from localStorage)."""
    root = ROOT / "scenes" / "grading" / "class"
    run_id = grade_example_over_api(server)
    phone.context.add_init_script(f"localStorage.setItem('grading.run', JSON.stringify('{run_id}'))")
    phone.context.add_init_script(f"localStorage.setItem('rt.instructor', JSON.stringify('{INSTRUCTOR}'))")
    page = phone.open("#grading").page
    assert page.get_attribute("#tab-grading", "aria-selected") == "true"

    # files: students by file name (named by the server: Unicode letters stay), kinds by extension;
    # a zip replaces them
    (tmp_path / "notes.txt").write_text("not a submission")
    zoe = tmp_path / "Zoë O'Brien.json"
    zoe.write_text((root / "alice.json").read_text())
    page.set_input_files("#grade-files", [root / "alice.json", root / "heidi.exr", tmp_path / "notes.txt", zoe])
    page.wait_for_selector("#grade-sub-rows tr[data-student=heidi]")
    kinds = page.eval_on_selector_all("#grade-sub-rows tr", "trs => trs.map(r => [r.dataset.student, r.dataset.kind])")
    assert kinds == [["alice", "scene"], ["heidi", "exr"], ["Zoë_O_Brien", "scene"]]
    assert "notes.txt" in page.text_content("#grade-sub-errors")
    with zipfile.ZipFile(tmp_path / "class.zip", "w") as z:
        z.write(root / "bob.json", "hw4/bob.json")
    page.set_input_files("#grade-files", tmp_path / "class.zip")
    page.wait_for_selector("#grade-sub-rows tr[data-kind=zip]")
    assert page.locator("#grade-sub-rows tr").count() == 1

    # the last run came back: the table scrolls inside its box, the page does not
    page.wait_for_selector("#grade-table", timeout=GRADE_TIMEOUT)
    assert table_rows(page) == {k: list(v) for k, v in EXPECTED.items()}
    width = page.evaluate("() => document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the page is {width} px wide on a {PHONE['width']} px screen"
    box = page.eval_on_selector(".grade-table-box", "b => [b.scrollWidth, b.clientWidth]")
    assert box[0] > box[1], box
    page.locator("#grade-results").scroll_into_view_if_needed()
    shot(page, "phone-table")

    page.click("#grade-table tr[data-student=erin] th")
    wait_pictures(page)
    flip_test = page.locator('#grade-detail-tests li[data-test="FLIP against the reference"]')
    assert flip_test.get_attribute("data-status") == "failed"
    width = page.evaluate("() => document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the page is {width} px wide with the detail open"
    page.wait_for_timeout(600)  # the smooth scroll to the detail ends
    page.evaluate("() => window.scrollTo(0, document.querySelector('#grade-detail').offsetTop - 8)")
    shot(page, "phone-erin")
    shot(page, "phone-full", full_page=True)


def test_web_grading_asks_for_the_instructor_s_token(desktop, server):
    """Without the instructor's token the tab says what it needs, and points at the field; with a wrong one,
    that the server refused it; with the right one it works, and the token is kept for the next visit."""
    desktop.allow.append(r"status of 401")  # Chromium logs the refused requests
    page = open_grading(desktop, token=None)
    assert page.input_value("#grade-token") == ""
    page.click("#grade-load-example")
    page.wait_for_selector("#grade-token[aria-invalid=true]")
    assert page.text_content("#grade-status") == "The server needs the instructor's token: enter it above."
    assert page.evaluate("() => document.activeElement.id") == "grade-token"
    assert "instructor's token" in page.text_content("#grade-errors")
    shot(page, "desktop-token")
    enter_token(page, "not-the-instructor-token")
    page.click("#grade-load-example")
    page.wait_for_function(
        "() => document.querySelector('#grade-status').textContent.includes('refused the instructor token')"
    )
    enter_token(page, INSTRUCTOR)
    assert page.get_attribute("#grade-token", "aria-invalid") is None
    load_example(page)
    page.reload()
    page.wait_for_selector("body[data-ready=true]", state="attached")
    page.click("#tab-grading")
    assert page.input_value("#grade-token") == INSTRUCTOR  # kept in this browser
