"""The student's view of an assignment (web/assignment.html at /assignments/{id}, web/js/course/) in a real browser.

`python -m server` on loopback with one render worker, an instructor token and an hourly cap of 3 submissions,
and Debian's Chromium through Playwright (test_web_page's `browser`). An assignment is published through the
API with a tiny reference (32 x 24 pixels, 16 spp: graded in about a second), a roster uploaded, and each test
opens one student's mailed link in a fresh browser context (its own localStorage), in New York's time zone,
failing on any console error it did not expect. The server's clock is the real one here (a subprocess):
deadlines are a day away, or already passed (an assignment published late, an extension to an hour ago) when a
test needs them passed; nothing waits for one. Screenshots go to $WEB_SHOTS (/tmp/web_shots).
"""

from __future__ import annotations

import json
import math
import re
from datetime import UTC, datetime, timedelta

import httpx
import pytest

from tests.support.api import INSTRUCTOR, Server, bearer, long_scene, wait_for
from tests.support.page import DESKTOP, PHONE, SHOTS, TEACHER, Page
from tests.support.page import render as render_in_workspace
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
SIZE = (32, 24)  # the assignment's film: every render is graded at it
TIMEZONE = "America/New_York"
GRADED = ("graded", "invalid", "failed")
NOT_FOUND = r"Failed to load resource: the server responded with a status of 404"


PER_HOUR = 3  # TRACER_MAX_SUBMISSIONS_PER_HOUR of these tests' server (a student's submissions in any hour)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    env = {"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR, "TRACER_MAX_SUBMISSIONS_PER_HOUR": str(PER_HOUR)}
    with Server(tmp_path_factory.mktemp("web-assignment-data"), workers=1, env=env) as s:
        yield s


def reference() -> dict:
    ref = json.loads((EXAMPLE / "reference.json").read_text())
    ref["film"] = {"width": SIZE[0], "height": SIZE[1]}
    ref["sampler"] = {"type": "jittered", "spp": 4}
    return ref


def spec() -> dict:
    s = json.loads((EXAMPLE / "assignment.json").read_text())
    s["render"] = {"width": SIZE[0], "height": SIZE[1], "seed": 7}
    s["reference"]["scene"] = reference()
    s["reference"]["spp"] = 16
    s["image"] = {"spp": 4}
    return s


def starter() -> dict:
    """The floor and the glass ball of the reference, without the rest: a student starts from it."""
    s = reference()
    s["name"] = "HW 4 starter: the floor and a glass ball"
    s["objects"] = s["objects"][:2]
    return s


def blue_ball() -> dict:
    """The reference with its red ball blue: full marks on the requirements, a difference on the ball."""
    s = reference()
    s["materials"]["red"]["kd"] = [0.1, 0.2, 0.8]
    return s


def publish(server, **policy) -> str:
    deadline = (datetime.now(UTC) + timedelta(days=1)).isoformat()
    body = {"spec": spec(), "deadline": deadline, **policy}
    r = httpx.post(f"{server.url}/api/assignments", json=body, headers=TEACHER, timeout=60)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    ready = lambda: httpx.get(f"{server.url}/api/assignments/{aid}/reference.png", headers=TEACHER, timeout=30)  # noqa: E731
    wait_for(lambda: ready().status_code == 200, 120, "the reference rendered", interval=0.2)
    return aid


def roster(server, aid: str, ids: list[str]) -> dict[str, dict]:
    text = "id,name,email\n" + "".join(f"{i},Student {i.upper()},{i}@school.edu\n" for i in ids)
    r = httpx.post(f"{server.url}/api/assignments/{aid}/roster", content=text,
                   headers={**TEACHER, "Content-Type": "text/csv"}, timeout=30)  # fmt: skip
    assert r.status_code == 200, r.text
    return {s["id"]: s for s in r.json()["students"]}


@pytest.fixture(scope="module")
def hw(server):
    """The assignment of these tests: a starter, the reference shown, 3 attempts, a late day at 20 % off, every
    test's feedback shown at once but one requirement's (never), the score too, and one student per test."""
    policy = {
        "starter": starter(),
        "show_reference": True,
        "max_submissions": 3,
        "late_until": (datetime.now(UTC) + timedelta(days=2)).isoformat(),
        "late_penalty": 0.2,
        "feedback": {"tests": {"a small scene": "never"}, "score": "now"},
    }
    aid = publish(server, **policy)
    students = roster(server, aid, ["brief", "start", "keep", "check", "submit", "image", "pixel", "late", "burst"])
    return {"id": aid, "students": students}


class Student(Page):
    """A student's own browser (a lent context in TIMEZONE) with its console watched, its errors with their place."""

    def __init__(self, browser, server, allow=()):
        super().__init__(browser, server, DESKTOP, timezone_id=TIMEZONE)
        self.allow = list(allow)

    def console_error(self, message) -> str:
        return f"console: {message.text} {message.location}"

    def open(self, url: str):
        self.page.goto(url)
        self.page.wait_for_selector("body[data-ready=true]", state="attached")
        return self.page

    def shot(self, name: str, full_page: bool = True) -> None:
        self.page.screenshot(path=str(SHOTS / f"assignment-{name}.png"), full_page=full_page)


@pytest.fixture
def student(browser, server):
    made = []

    def make(allow=()):
        s = Student(browser, server, allow)
        made.append(s)
        return s

    yield make
    for s in made:
        s.context.close()
    for s in made:
        assert s.unexpected_errors() == []


def set_scene(page, scene: dict | str) -> None:
    page.fill("#a-scene", scene if isinstance(scene, str) else json.dumps(scene, indent=2))


def sub_rows(page) -> list[dict]:
    """Your submissions as shown, newest first."""
    return page.evaluate(
        """() => [...document.querySelectorAll('#a-sub-list li.a-sub')].map(li => ({
            id: li.dataset.id, status: li.dataset.status, late: li.dataset.late, counts: li.dataset.counts,
            head: li.querySelector('.a-sub-head').textContent}))"""
    )


def wait_status(page, sid: str, status: str, timeout: float = 60_000) -> None:
    page.wait_for_function(
        "([sid, st]) => document.querySelector(`#a-sub-list li[data-id='${sid}']`)?.dataset.status === st",
        arg=[sid, status],
        timeout=timeout,
    )


def api_submissions(server, aid: str, token: str) -> list[dict]:
    r = httpx.get(f"{server.url}/api/assignments/{aid}/submissions", headers=bearer(token), timeout=30)
    assert r.status_code == 200, r.text
    return r.json()["submissions"]


# --------------------------------------------------------------------------------------------------


def test_student_link_keeps_the_token_out_of_the_address_bar_and_shows_the_brief(student, server, hw):
    s = hw["students"]["brief"]
    me = student()
    page = me.open(s["link"])
    assert "#token" not in page.url
    assert s["token"] not in page.url
    kept = page.evaluate(f"() => JSON.parse(localStorage.getItem('rt.course.{hw['id']}.token'))")
    assert kept == s["token"]
    assert page.evaluate("() => JSON.parse(localStorage.getItem('rt.token'))") == s["token"]  # the workspace's too

    assert page.text_content("#a-name") == "HW 4: glass, mirrors and soft shadows"
    assert "Student BRIEF" in page.text_content("#a-who")
    points = dict(
        page.eval_on_selector_all(
            "#a-points tbody tr", "trs => trs.map(tr => [tr.dataset.test, tr.querySelector('td.num').textContent])"
        )
    )
    assert points == {"validity": "1", "a glass object": "2", "an area light": "1", "three bounces": "1",
                      "a small scene": "1", "a render budget": "1",
                      "flip": "2", "ssim": "1", "psnr": "1", "pixels": "2"}  # fmt: skip
    shown = page.text_content("#a-points tbody tr[data-test='a small scene']")
    assert "instructor only" in shown
    assert page.text_content("#a-max").startswith("13")
    # the deadline in the student's zone, and the time left counting down from the server's
    deadline = page.text_content("#a-deadline")
    assert re.search(r"\b(EST|EDT|GMT-5|GMT-4)\b", deadline), deadline
    left = page.text_content("#a-time-left")
    assert re.fullmatch(r"23 h 5\d min \d+ s", left), left
    page.wait_for_function("(t) => document.querySelector('#a-time-left').textContent !== t", arg=left, timeout=5000)
    assert "20 %" in page.text_content("#a-late")
    assert page.get_attribute("#a-left", "data-left") == "3"
    page.wait_for_function(
        "() => { const i = document.querySelector('#a-reference'); return i.complete && i.naturalWidth === 32; }"
    )
    assert page.get_attribute("#a-reference", "src").startswith("blob:")
    assert page.text_content("#a-subs-status").startswith("None yet")
    guide = page.get_attribute("#link-guide", "href")
    assert guide == "/reference/assignments.md"
    assert httpx.get(f"{server.url}{guide}", timeout=30).status_code == 200
    me.shot("brief")
    page.set_viewport_size({"width": 1024, "height": 700})  # a small laptop: hand-in and submissions stacked
    assert page.evaluate("() => document.documentElement.scrollWidth <= 1024")  # nothing wider than the window
    me.shot("brief-1024")
    page.set_viewport_size(PHONE)
    me.shot("brief-phone")
    wide = page.evaluate(
        "() => [...document.querySelectorAll('body *')].filter(e => e.getBoundingClientRect().right > 391)"
        ".map(e => `${e.tagName}#${e.id}.${e.className}`)"
    )
    assert wide == []  # nothing wider than a phone
    page.set_viewport_size(DESKTOP)

    # a later visit without the fragment uses the kept token
    page = me.open(f"{server.url}/assignments/{hw['id']}")
    assert page.text_content("#a-name") == "HW 4: glass, mirrors and soft shadows"
    assert page.is_visible("#a-brief")
    assert not page.is_visible("#a-access")


def test_start_opens_the_workspace_with_the_starter_scene_and_a_way_back(student, server, hw, tmp_path):
    s = hw["students"]["start"]
    me = student()
    page = me.open(s["link"])
    assert page.is_visible("#a-start")
    page.click("#a-start")
    page.wait_for_url(f"{server.url}/")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert json.loads(page.input_value("#scene-text")) == starter()
    back = page.locator("#working-on")
    assert back.is_visible()
    assert "HW 4: glass, mirrors and soft shadows" in back.text_content()
    assert page.get_attribute("#working-back", "href") == f"/assignments/{hw['id']}"
    me.shot("workspace-working-on", full_page=False)

    # the workspace's scene, changed there, is handed in from the assignment's page
    mine = starter()
    mine["objects"].append(reference()["objects"][3])
    page.fill("#scene-text", json.dumps(mine, indent=2))
    page.wait_for_function("() => document.querySelector('#validation-status').dataset.kind !== 'busy'")
    page.wait_for_timeout(400)  # the editor keeps its text 0.3 s after the last keystroke
    page.click("#working-back")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert page.url == f"{server.url}/assignments/{hw['id']}"
    page.click("#a-from-workspace")
    assert json.loads(page.input_value("#a-scene")) == mine
    assert "Took the scene in the workspace's editor" in page.text_content("#a-scene-note")

    # or a .json file of the student's
    (tmp_path / "mine.json").write_text(json.dumps(reference()))
    page.set_input_files("#a-scene-file", str(tmp_path / "mine.json"))
    page.wait_for_function("() => document.querySelector('#a-scene-note').textContent === 'Opened mine.json.'")
    assert json.loads(page.input_value("#a-scene")) == reference()


def workspace_scene(page, scene: dict) -> None:
    """Type `scene` into the workspace's editor, and wait until the editor has kept it (0.3 s after the last
    keystroke) and the server has checked it."""
    page.fill("#scene-text", json.dumps(scene, indent=2))
    page.wait_for_function("() => document.querySelector('#validation-status').dataset.kind !== 'busy'")
    kept = "(t) => JSON.parse(localStorage.getItem('rt.editor.text')) === t"
    page.wait_for_function(kept, arg=json.dumps(scene, indent=2))


def kept_scene(page) -> dict:
    return json.loads(page.evaluate("() => JSON.parse(localStorage.getItem('rt.editor.text'))"))


def test_a_link_keeps_the_earlier_jobs_and_start_asks_before_replacing_a_built_scene(student, server, hw):
    """#42: the renders a browser made before an assignment's link made it the student's stay in "my jobs" and
    open (each with the token that submitted it; no 404 in the console), and "Start from the starter scene" asks
    before it replaces a scene the student built: Cancel keeps it, Replace replaces it; the starter is not asked
    about again."""
    s = hw["students"]["keep"]
    me = student()  # no console error allowed: a refused look at the earlier job would be one
    page = me.open(f"{server.url}/")
    mine = reference()
    mine["name"] = "my scene from before the course"
    workspace_scene(page, mine)
    render_in_workspace(page)
    earlier = page.get_attribute("#stage", "data-job")
    before = page.evaluate("() => JSON.parse(localStorage.getItem('rt.token'))")

    page = me.open(s["link"])
    assert page.evaluate("() => JSON.parse(localStorage.getItem('rt.token'))") == s["token"] != before
    # the student's token does not own the earlier job: only the token that submitted it opens it
    assert httpx.get(f"{server.url}/api/jobs/{earlier}", headers=bearer(s["token"]), timeout=30).status_code == 404

    page = me.open(f"{server.url}/")
    page.wait_for_selector(f"#job-list li[data-id='{earlier}']", timeout=20_000)
    mine["name"] = "my scene in the course"
    workspace_scene(page, mine)
    render_in_workspace(page)
    now = page.get_attribute("#stage", "data-job")
    theirs = httpx.get(f"{server.url}/api/jobs", headers=bearer(s["token"]), timeout=30).json()["jobs"]
    assert [j["id"] for j in theirs] == [now]
    listed = "(ids) => ids.every(id => document.querySelector(`#job-list li[data-id='${id}']`))"
    page.wait_for_function(listed, arg=[earlier, now])
    page.click(f"#job-list li[data-id='{earlier}'] .job-open")
    shown = "(id) => { const d = document.querySelector('#stage').dataset; return d.job === id && d.status === 'done' }"
    page.wait_for_function(shown, arg=earlier)
    page.wait_for_function("() => document.querySelector('#render-img').naturalWidth === 32")

    # Start, with a scene of the student's in the editor: asked, and Cancel keeps it
    page = me.open(f"{server.url}/assignments/{hw['id']}")
    assert page.is_hidden("#a-start-ask")
    page.click("#a-start")
    page.wait_for_selector("#a-start-ask", state="visible")
    assert "Replace your scene?" in page.text_content("#a-start-ask")
    assert page.evaluate("() => document.activeElement.id") == "a-start-cancel"
    me.shot("start-asks")
    page.click("#a-start-cancel")
    assert page.is_hidden("#a-start-ask")
    assert page.url == f"{server.url}/assignments/{hw['id']}"
    assert kept_scene(page) == mine
    # Replace: the workspace opens with the starter in the editor
    page.click("#a-start")
    page.click("#a-start-replace")
    page.wait_for_url(f"{server.url}/")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert json.loads(page.input_value("#scene-text")) == starter()
    # the starter in the editor: Start goes straight to the workspace
    page = me.open(f"{server.url}/assignments/{hw['id']}")
    page.click("#a-start")
    page.wait_for_url(f"{server.url}/")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert json.loads(page.input_value("#scene-text")) == starter()
    assert me.unexpected_errors() == []


def test_check_shows_each_tests_result_and_the_errors_at_their_paths(student, server, hw):
    s = hw["students"]["check"]
    me = student()
    page = me.open(s["link"])
    bad = reference()
    bad["objects"][1]["radius"] = -0.7
    set_scene(page, bad)
    page.click("#a-check")
    page.wait_for_selector("#a-check-result[data-valid=false]", timeout=30_000)
    assert "The scene is invalid" in page.text_content("#a-check-verdict")
    assert "No attempt was used" in page.text_content("#a-check-verdict")
    paths = page.eval_on_selector_all("#a-check-body .a-problems li", "lis => lis.map(li => li.dataset.path)")
    assert "objects[1].radius" in paths
    page.click("#a-check-body .a-problems li[data-path='objects[1].radius'] .a-jump")
    selected = page.evaluate(
        "() => { const t = document.querySelector('#a-scene'); return t.value.slice(t.selectionStart, t.selectionEnd) }"
    )
    assert selected.strip() == "-0.7"

    # broken JSON: sent as text, the server's syntax error names its line, and the page goes there
    text = json.dumps(reference(), indent=2).replace('"vfov": 40', '"vfov": 40,,')
    set_scene(page, text)
    page.click("#a-check")
    page.wait_for_selector("#a-check-result[data-valid=false]", timeout=30_000)
    assert "The scene is invalid: 1 error." in page.text_content("#a-check-verdict")
    errors = page.text_content("#a-check-body .a-problems")
    line = text[: text.index(",,")].count("\n") + 1
    assert f"line {line}" in errors, errors
    page.click("#a-check-body .a-problems .a-jump")
    caret = page.evaluate(
        "() => { const t = document.querySelector('#a-scene'); return t.value.slice(t.selectionStart, t.selectionEnd) }"
    )
    assert '"vfov": 40,,' in caret

    # a valid scene without glass: the requirements' results in seconds, the hidden one by name only
    no_glass = reference()
    no_glass["materials"]["glass"] = {"kd": 0.5}
    set_scene(page, no_glass)
    page.click("#a-check")
    page.wait_for_selector("#a-check-result[data-valid=true]", timeout=30_000)
    tests = dict(
        page.eval_on_selector_all("#a-check-tests li", "lis => lis.map(li => [li.dataset.test, li.dataset.status])")
    )
    assert tests == {"validity": "passed", "a glass object": "failed", "an area light": "passed",
                     "three bounces": "passed", "a small scene": "hidden", "a render budget": "passed"}  # fmt: skip
    assert "shown never" in page.text_content("#a-check-tests li[data-test='a small scene']")
    assert "found 0 materials" in page.text_content("#a-check-tests li[data-test='a glass object']")
    assert "flip, ssim, psnr, pixels" in page.text_content("#a-check-body")
    me.shot("check")
    # nothing kept, no attempt used
    assert api_submissions(server, hw["id"], s["token"]) == []
    assert page.get_attribute("#a-left", "data-left") == "3"


def test_an_invalid_then_a_valid_submission_graded_live(student, server, hw):
    s = hw["students"]["submit"]
    me = student()
    page = me.open(s["link"])
    page.evaluate("() => (window.__sameDocument = true)")  # gone if the page reloads

    bad = reference()
    bad["objects"][1]["radius"] = -0.7
    set_scene(page, bad)
    page.click("#a-submit")
    page.wait_for_selector("#a-sub-list li.a-sub")
    assert "Submitted at" in page.text_content("#a-submit-status")
    sid_bad = sub_rows(page)[0]["id"]
    wait_status(page, sid_bad, "invalid")
    row = page.locator(f"#a-sub-list li[data-id='{sid_bad}']")
    assert "no attempt used" in row.text_content()
    assert row.locator(".a-problems li[data-path='objects[1].radius']").count() == 1
    page.wait_for_function("() => document.querySelector('#a-left').dataset.left === '3'")

    # a long job holds the only worker: the valid submission waits, queued, where the page shows it
    busy = httpx.post(f"{server.url}/api/jobs", json={"scene": long_scene()}, headers=TEACHER, timeout=30).json()["id"]
    job_url = f"{server.url}/api/jobs/{busy}"
    try:
        wait_for(
            lambda: httpx.get(job_url, headers=TEACHER, timeout=30).json()["status"] == "running", 60, "the long job"
        )
        set_scene(page, reference())
        page.click("#a-submit")
        page.wait_for_function("() => document.querySelectorAll('#a-sub-list li.a-sub').length === 2")
        sid = sub_rows(page)[0]["id"]
        assert sid != sid_bad
        assert sub_rows(page)[0]["status"] in ("queued", "grading")  # taken up by the run, its render waiting
        assert "holds an attempt" in sub_rows(page)[0]["head"]
    finally:
        httpx.delete(job_url, headers=TEACHER, timeout=30)
    wait_status(page, sid, "graded")
    assert page.evaluate("() => window.__sameDocument") is True  # no reload: the event stream brought it
    said = page.text_content("#a-subs-status")  # the live region's words
    assert re.fullmatch(r"Submission #2 is graded: \d+(\.\d+)? / 13\.", said), said
    row = page.locator(f"#a-sub-list li[data-id='{sid}']")
    page.wait_for_function(
        f"() => document.querySelector(\"#a-sub-list li[data-id='{sid}']\").dataset.counts === 'true'"
    )
    head = row.locator(".a-sub-head").text_content()
    assert "13 / 13" in head or "12 / 13" in head or "11 / 13" in head, head  # the image tests within noise
    assert "an attempt" in head
    assert "counts" in head
    statuses = dict(
        row.locator(".a-tests li").evaluate_all("lis => lis.map(li => [li.dataset.test, li.dataset.status])")
    )
    assert statuses["validity"] == "passed"
    assert statuses["a glass object"] == "passed"
    assert statuses["a small scene"] == "hidden"
    figs = row.locator("figure.a-fig").evaluate_all("fs => fs.map(f => f.dataset.picture)")
    assert figs == ["render.png", "error_map.png", "rejected.png", "reference.png"]
    page.wait_for_function(
        f"""() => [...document.querySelectorAll("#a-sub-list li[data-id='{sid}'] figure img")]
            .every(i => i.complete && i.naturalWidth === 32)"""
    )
    page.wait_for_function("() => document.querySelector('#a-left').dataset.left === '2'")
    assert [r["status"] for r in api_submissions(server, hw["id"], s["token"])] == ["invalid", "graded"]
    me.shot("graded")


def test_an_image_from_the_students_own_ray_tracer(student, server, hw, tmp_path):
    s = hw["students"]["image"]
    r = httpx.post(f"{server.url}/api/jobs", json={"scene": reference()}, headers=bearer(s["token"]), timeout=30)
    job = r.json()["id"]
    wait_for(
        lambda: (
            httpx.get(f"{server.url}/api/jobs/{job}", headers=bearer(s["token"]), timeout=30).json()["status"] == "done"
        ),
        60,
        "the render",
    )
    png = httpx.get(f"{server.url}/api/jobs/{job}/image?format=png", headers=bearer(s["token"]), timeout=30).content
    (tmp_path / "mine.png").write_bytes(png)
    me = student()
    page = me.open(s["link"])
    page.check("#a-kind-image")
    assert page.is_visible("#a-image")
    assert not page.is_visible("#a-scene")
    page.set_input_files("#a-image", str(tmp_path / "mine.png"))
    page.wait_for_function("() => document.querySelector('#a-image-note').textContent.includes('PNG')")
    page.click("#a-submit")
    page.wait_for_selector("#a-sub-list li.a-sub")
    sid = sub_rows(page)[0]["id"]
    wait_status(page, sid, "graded")
    head = sub_rows(page)[0]["head"]
    assert "PNG image" in head and "/ 7" in head, head
    # the same render as an OpenEXR file (floats): the page sends it as EXR, and Check reads it (no attempt)
    exr = httpx.get(f"{server.url}/api/jobs/{job}/image?format=exr", headers=bearer(s["token"]), timeout=30).content
    (tmp_path / "mine.exr").write_bytes(exr)
    page.set_input_files("#a-image", str(tmp_path / "mine.exr"))
    page.wait_for_function("() => document.querySelector('#a-image-note').textContent.includes('EXR')")
    page.click("#a-check")
    page.wait_for_selector("#a-check-verdict")
    assert page.text_content("#a-check-verdict") == "The image can be read. No attempt was used."
    assert page.get_attribute("#a-check-result", "data-valid") == "true"
    # the job the student rendered with their link's token is theirs in the workspace too
    page = me.open(f"{server.url}/")
    page.wait_for_selector(f"#job-list li[data-id='{job}']")


def test_a_browser_without_the_link_gets_no_data_and_a_bad_token_a_clear_message(student, server, hw):
    me = student(allow=[NOT_FOUND])
    asked = []
    me.page.on("request", lambda r: "/api/assignments" in r.url and asked.append(r.url))
    page = me.open(f"{server.url}/assignments/{hw['id']}")
    assert page.is_visible("#a-access")
    assert not page.is_visible("#a-brief")
    assert not page.is_visible("#a-work")
    assert "personal link" in page.text_content("#a-access-why")
    assert "HW 4" not in page.text_content("body")
    assert asked == []  # without a token, nothing is asked
    me.shot("no-link", full_page=False)

    page.goto("about:blank")  # (the same page with only a new fragment would not load again)
    page = me.open(f"{server.url}/assignments/{hw['id']}#token=not-a-token-of-this-class")
    assert "#token" not in page.url
    assert page.is_visible("#a-access")
    assert "does not know this link" in page.text_content("#a-access-why")
    assert "HW 4" not in page.text_content("body")
    assert page.evaluate(f"() => localStorage.getItem('rt.course.{hw['id']}.token')") is None  # not kept

    # joining by name: this assignment is not open
    page.fill("#a-join-name", "Mallory")
    page.click("#a-join-go")
    page.wait_for_function("() => document.querySelector('#a-join-status').textContent.includes('not open')")


def test_an_open_assignment_is_joined_by_a_name(student, server):
    aid = publish(server, open=True)
    me = student()
    page = me.open(f"{server.url}/assignments/{aid}")
    assert page.is_visible("#a-join")
    page.fill("#a-join-name", "Zoë O'Brien")
    page.click("#a-join-go")
    page.wait_for_selector("#a-brief:not([hidden])")
    assert "Zoë O'Brien" in page.text_content("#a-who")
    assert "self-declared" in page.text_content("#a-who")
    link = page.input_value("#a-own-link")
    assert link.startswith(f"{server.url}/assignments/{aid}#token=")
    assert page.evaluate(f"() => JSON.parse(localStorage.getItem('rt.course.{aid}.token'))") == link.split("#token=")[1]


def test_refusals_are_the_servers_own_words_in_place(student, server, hw):
    """Past the cut-off (a deadline an hour ago), with no attempts left, and past the hourly cap: each the
    server's 403 or 429, said where the Submit button is, with nothing added to the list."""
    closed = publish(server, deadline=(datetime.now(UTC) - timedelta(hours=1)).isoformat())
    one = publish(server, max_submissions=1)
    a = roster(server, closed, ["late"])["late"]
    b = roster(server, one, ["once"])["once"]
    me = student(allow=[r"status of 403"])
    page = me.open(a["link"])
    assert page.get_attribute("#a-time-left", "data-phase") == "closed"
    assert "closed" in page.text_content("#a-phase")
    set_scene(page, reference())
    page.click("#a-submit")
    page.wait_for_function("() => document.querySelector('#a-submit-status').dataset.kind === 'error'")
    text = page.text_content("#a-submit-status")
    assert text.startswith("Not accepted: the deadline was ") and "this submission came at" in text, text
    assert page.locator("#a-sub-list li").count() == 0

    page = me.open(b["link"])
    set_scene(page, reference())
    page.click("#a-submit")
    page.wait_for_selector("#a-sub-list li.a-sub")
    page.click("#a-submit")  # the first still holds its attempt, graded or not
    page.wait_for_function("() => document.querySelector('#a-submit-status').dataset.kind === 'error'")
    assert "no submissions left: 1 used" in page.text_content("#a-submit-status")
    assert page.locator("#a-sub-list li.a-sub").count() == 1

    # invalid scenes cost no attempt, but the hourly cap counts every submission
    page = me.open(hw["students"]["burst"]["link"])
    me.allow.append(r"status of 429")
    set_scene(page, '{"version": 1, "camera": 7}')
    for n in range(1, PER_HOUR + 1):
        page.click("#a-submit")
        page.wait_for_function(f"() => document.querySelectorAll('#a-sub-list li.a-sub').length === {n}")
    page.click("#a-submit")
    page.wait_for_function("() => document.querySelector('#a-submit-status').dataset.kind === 'error'")
    said = page.text_content("#a-submit-status")
    assert (
        said
        == f"Not accepted: at most {PER_HOUR} submissions per hour (TRACER_MAX_SUBMISSIONS_PER_HOUR); try again later."
    )
    assert page.locator("#a-sub-list li.a-sub").count() == PER_HOUR


def test_a_late_submission_is_marked_and_its_penalty_said(student, server, hw):
    """An extension to an hour ago moves this student's deadline and late cut-off back alike: they are in their
    late day (by the server's clock, no waiting), and their submission is late, 20 % off."""
    s = hw["students"]["late"]
    an_hour_ago = (datetime.now(UTC) - timedelta(hours=1)).isoformat()
    r = httpx.post(f"{server.url}/api/assignments/{hw['id']}/extensions", headers=TEACHER, timeout=30,
                   json={"student": "late", "deadline": an_hour_ago})  # fmt: skip
    assert r.status_code == 200, r.text
    me = student()
    page = me.open(s["link"])
    assert page.get_attribute("#a-time-left", "data-phase") == "late"
    assert re.fullmatch(
        r"the deadline has passed; 2[23] h \d+ min \d+ s left to hand in late", page.text_content("#a-time-left")
    )
    assert "marked late and loses 20 % of its points" in page.text_content("#a-phase")
    set_scene(page, reference())
    page.click("#a-submit")
    page.wait_for_selector("#a-sub-list li.a-sub")
    assert "(late)" in page.text_content("#a-submit-status")
    sid = sub_rows(page)[0]["id"]
    wait_status(page, sid, "graded")
    row = sub_rows(page)[0]
    assert row["late"] == "true"
    assert "late" in row["head"]
    view = httpx.get(f"{server.url}/api/assignments/{hw['id']}/submissions/{sid}", headers=bearer(s["token"])).json()
    assert view["late"]
    assert view["penalty"] == 0.2
    assert view["score"] == round(0.8 * view["raw_score"], 6)
    assert f"{view['score']:g} / 13" in row["head"]
    note = page.text_content(f"#a-sub-list li[data-id='{sid}'] .a-score-note")
    assert note == f"Late: 20 % of the points taken off ({view['raw_score']:g} before the penalty)."


def pixel_of(scene: dict, point: list[float]) -> tuple[int, int]:
    """Where a point of the scene is on its film: the pinhole camera of scene-format.md (vfov vertical)."""
    cam = scene["camera"]
    eye, at = cam["lookfrom"], cam["lookat"]
    up = cam.get("vup", [0, 1, 0])
    sub = lambda a, b: [a[i] - b[i] for i in range(3)]  # noqa: E731
    dot = lambda a, b: sum(a[i] * b[i] for i in range(3))  # noqa: E731
    cross = lambda a, b: [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]  # noqa: E731
    unit = lambda a: [x / math.sqrt(dot(a, a)) for x in a]  # noqa: E731
    w = unit(sub(eye, at))
    u = unit(cross(up, w))
    v = cross(w, u)
    d = sub(point, eye)
    depth = -dot(d, w)
    half_h = math.tan(math.radians(cam["vfov"]) / 2)
    half_w = half_h * SIZE[0] / SIZE[1]
    x = (dot(d, u) / depth / half_w + 1) / 2 * SIZE[0]
    y = (1 - dot(d, v) / depth / half_h) / 2 * SIZE[1]
    return int(x), int(y)


def test_student_clicks_a_pixel_of_the_difference_map(student, server, hw):
    """The red ball made blue: a click on the ball in the difference map shows both ray trees there (compare.js,
    helper R's), the first node where they differ marked. Fails until web/js/course/compare.js is merged."""
    s = hw["students"]["pixel"]
    x, y = pixel_of(reference(), reference()["objects"][3]["center"])
    tree = httpx.post(
        f"{server.url}/api/raytree", json={"scene": reference(), "x": x, "y": y}, headers=TEACHER, timeout=60
    )
    assert tree.json()["nodes"][0]["hit"]["object_name"] == "red ball", (x, y)  # the pixel is on the ball

    me = student()
    page = me.open(s["link"])
    set_scene(page, blue_ball())
    page.click("#a-submit")
    page.wait_for_selector("#a-sub-list li.a-sub")
    sid = sub_rows(page)[0]["id"]
    wait_status(page, sid, "graded")
    img = page.locator(f"#a-sub-list li[data-id='{sid}'] img[data-picture='error_map.png']")
    page.wait_for_function("(el) => el.complete && el.naturalWidth === 32", arg=img.element_handle())
    box = img.bounding_box()
    with page.expect_request(re.compile(r"/raytree\?")) as asked:
        img.click(position={"x": (x + 0.5) * box["width"] / SIZE[0], "y": (y + 0.5) * box["height"] / SIZE[1]})
    query = dict(p.split("=") for p in asked.value.url.split("?", 1)[1].split("&"))
    assert (int(query["x"]), int(query["y"])) == (x, y)
    assert f"/api/assignments/{hw['id']}/submissions/{sid}/raytree" in asked.value.url
    page.wait_for_selector("#compare section.compare-side, #compare p.compare-error")  # after its "Tracing..."
    assert page.locator("#compare p.compare-error").count() == 0, page.text_content("#compare")
    sides = page.eval_on_selector_all("#compare div.compare section.compare-side", "ss => ss.map(s => s.dataset.side)")
    assert sides == ["student", "reference"]
    assert page.locator("#compare .differs").count() >= 1
    # the comparison sits under the difference map, in the submission's feedback
    mine = f"#a-sub-list li[data-id='{sid}']"
    assert page.evaluate("(sel) => document.querySelector(sel).contains(document.querySelector('#compare'))", mine)
    me.shot("compare")

    # with the keyboard: the arrows move the chosen pixel, Enter compares there
    img.focus()
    page.keyboard.press("ArrowRight")
    with page.expect_request(re.compile(r"/raytree\?")) as asked:
        page.keyboard.press("Enter")
    query = dict(p.split("=") for p in asked.value.url.split("?", 1)[1].split("&"))
    assert (int(query["x"]), int(query["y"])) == (x + 1, y)
