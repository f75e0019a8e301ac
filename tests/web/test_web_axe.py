"""Accessibility (WCAG 2.1 AA) of every page, checked with axe-core in Debian's Chromium (Playwright).

axe-core's rules tagged wcag2a, wcag2aa, wcag21a and wcag21aa (and two more, RULES) run on each page in the
states a person sees: the workspace after a render and a click on a pixel (the picture and the ray-tree views
shown), with a radiosity job's panel, its Lessons tab with one lesson open, its Examples tab, its Grading tab
(empty, then the example class graded and a student's detail); /course with an assignment published and its
dashboard filled by one graded submission; the student's assignment page with that submission and two ray
trees compared at a pixel of its difference map; the /reference/ pages (the index and scene-format.md); a
student's course page, /course's courses panel and a refused LTI launch. No violation of impact "serious" or
"critical" may remain; the assertion lists each one with its rule, help text and first targets. axe-core's script is the
one bundled in the `axe-playwright-python` package (the test extras): nothing is fetched at test time.

The ray tree's text form (the list a screen reader follows) is read too: it names the eye ray and a shadow
ray of a known pixel, with what each hit, its weight and the colour it carried back, and the arrow keys walk
it; the rendered picture's description says the scene, its size, its samples and that it is done; the
radiosity mesh's patches are reached with the arrow keys.

One server (one render worker) and one browser for the module; small renders (64 x 48, a 32 x 32 radiosity
box, a 32 x 24 assignment). About 45 s on a 2-core machine shared with other work, most of it the renders,
the lesson's and the grading.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import httpx
import pytest

from tests.support.api import INSTRUCTOR, Server, bearer, run_solutions, wait_for
from tests.support.axe import assert_accessible
from tests.support.dashboard import good_scene, small_spec
from tests.support.grading_page import enter_token, load_example
from tests.support.page import DESKTOP, TEACHER, Page, radiosity_scene, render, run_lesson, set_scene, whitted

SIZE = (64, 48)  # the workspace's render: its ray tree in well under a second


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    env = {"TRACER_PREVIEW_INTERVAL": "0.1", "TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR, **run_solutions(tmp_path_factory)}
    with Server(tmp_path_factory.mktemp("web-axe-data"), workers=1, env=env) as s:
        yield s


@pytest.fixture
def desktop(browser, server):
    p = Page(browser, server, DESKTOP)
    yield p
    p.context.close()
    assert p.unexpected_errors() == []


@pytest.fixture(scope="module")
def course(server):
    """A small published assignment (its reference 32 x 24) with a roster of two, and one graded submission."""
    body = {"spec": small_spec(), "deadline": (datetime.now(UTC) + timedelta(days=1)).isoformat()}
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        r = c.post("/api/assignments", json=body)
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        roster = "id,name,email\ns1,Ada Lovelace,ada@x.edu\ns2,Bob Jones,\n"
        r = c.post(f"/api/assignments/{aid}/roster", content=roster, headers={"Content-Type": "text/csv"})
        assert r.status_code == 200, r.text
        students = {s["id"]: s for s in r.json()["students"]}
        r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": good_scene()},
                   headers=bearer(students["s1"]["token"]))  # fmt: skip
        assert r.status_code == 202, r.text
        sid = r.json()["id"]

        def graded():
            subs = c.get(f"/api/assignments/{aid}/submissions", headers=bearer(students["s1"]["token"])).json()
            return next((s for s in subs["submissions"] if s["id"] == sid and s["status"] == "graded"), None)

        wait_for(graded, 120, "the submission graded", interval=0.2)
    return {"id": aid, "students": students}


# -- the workspace ------------------------------------------------------------------------------------


def render_shown(page) -> None:
    """Render the editor's scene and wait until its final picture is the one shown: the description says it
    is done once the last image is in place (a click before that would trace over the last preview's picture,
    which the final one's arrival takes away)."""
    render(page)
    assert page.get_attribute("#stage", "data-status") == "done"
    page.wait_for_function("() => document.querySelector('#render-img').alt.includes(', done.')")


def click_pixel(page, x: int, y: int) -> None:
    img = page.locator("#render-img").bounding_box()
    w, h = SIZE
    page.mouse.click(img["x"] + (x + 0.5) * img["width"] / w, img["y"] + (y + 0.5) * img["height"] / h)
    page.wait_for_selector("#rt-diagram .rt-node")


def test_axe_workspace_with_a_render_and_a_ray_tree(desktop, server):
    page = desktop.open().page
    assert_accessible(page, "workspace at first")
    scene = whitted(*SIZE, spp=4)
    set_scene(page, scene)
    render_shown(page)
    # the glass ball's pixel (test_web_page's (112, 70) of 160 x 120): eye, reflection, transmission, shadow rays
    x, y = 112 * SIZE[0] // 160, 70 * SIZE[1] // 120
    click_pixel(page, x, y)
    page.locator("#raytree").scroll_into_view_if_needed()
    desktop.shot("axe-workspace-raytree", full_page=True)
    assert_accessible(page, "workspace with a ray tree")
    alt = page.get_attribute("#render-img", "alt")  # the picture says what it is
    assert scene["name"] in alt and "64 × 48" in alt and "4 samples per pixel" in alt and "done" in alt, alt


def test_axe_the_ray_tree_s_text_form_names_each_ray(desktop, server):
    """The tree as a nested list: the eye ray first, a shadow ray under it, each with its depth, what it hit
    (or that it missed), its weight and the colour it carried back; reachable with the keyboard."""
    page = desktop.open().page
    scene = whitted(*SIZE, spp=4)
    set_scene(page, scene)
    render_shown(page)
    x, y = 112 * SIZE[0] // 160, 70 * SIZE[1] // 120
    click_pixel(page, x, y)
    tree = httpx.post(f"{server.url}/api/raytree", json={"scene": scene, "x": x, "y": y, "sample": 0}, timeout=30)
    nodes = tree.json()["nodes"]
    items = page.locator("#rt-list [role=treeitem]")
    assert items.count() == len(nodes)
    eye = nodes[0]
    first = page.locator(f"#rt-list [role=treeitem][data-id='{eye['id']}']")
    text = first.locator(":scope > .rt-li-text").inner_text()
    assert text.startswith("Ray 0: eye ray, depth 1"), text
    assert eye["hit"]["object_name"] in text and "weight" in text and "carried back" in text, text
    assert first.get_attribute("aria-level") == "1"
    assert first.get_attribute("aria-expanded") == "true"
    shadow = next(n for n in nodes if n["kind"] == "shadow")
    said = page.locator(f"#rt-list [role=treeitem][data-id='{shadow['id']}'] > .rt-li-text").inner_text()
    assert said.startswith(f"Ray {shadow['id']}: shadow ray"), said
    assert ("blocked" in said) == bool(shadow["occluded"]) and f"light {shadow['light']}" in said, said
    # keyboard: one tab stop; the arrow keys walk the rays, and the ray's numbers follow
    page.focus(f"#rt-list [role=treeitem][data-id='{eye['id']}']")
    page.keyboard.press("ArrowDown")
    second = page.evaluate("() => document.activeElement.dataset.id")
    assert second == str(nodes[1]["id"])
    assert page.inner_text("#rt-details h3") == f"Ray #{nodes[1]['id']}"
    page.keyboard.press("ArrowLeft")  # to the parent
    assert page.evaluate("() => document.activeElement.dataset.id") == str(eye["id"])
    page.keyboard.press("ArrowLeft")  # collapses the eye ray
    assert first.get_attribute("aria-expanded") == "false"
    page.keyboard.press("ArrowRight")
    assert first.get_attribute("aria-expanded") == "true"


def test_axe_workspace_radiosity_panel_and_its_keys(desktop, server):
    """The radiosity panel (a small two-pass Cornell box): no violation, and the arrow keys on the patch mesh
    say a patch's numbers as hovering does."""
    page = desktop.open().page
    set_scene(page, radiosity_scene(32))
    render(page)
    page.wait_for_selector("#radiosity:not([hidden]) #rad-body:not([hidden])")
    assert_accessible(page, "workspace with the radiosity panel")
    page.focus("#rad-mesh")
    page.keyboard.press("ArrowRight")
    page.wait_for_function("() => document.querySelector('#rad-hover').textContent.includes('B = ')")
    said = page.inner_text("#rad-hover")
    page.keyboard.press("ArrowRight")
    page.wait_for_function("(t) => document.querySelector('#rad-hover').textContent !== t", arg=said)
    page.keyboard.press("Escape")
    page.wait_for_function("() => document.querySelector('#rad-hover').textContent === ''")


def test_axe_workspace_build_panel_with_a_pick(desktop, server):
    """The Build panel with an object picked (its handles, material menu and Remove): no violation, and its keys
    reach the pick and the move as the mouse does."""
    page = desktop.open().page
    page.select_option("#build-template", "empty_room")
    page.wait_for_function("() => document.querySelector('#scene-text').value.includes('\"objects\": []')")
    page.click("#build-add-sphere")
    page.click("#build-light-quad")
    page.focus("#build-3d")
    page.keyboard.press("n")
    assert page.get_attribute("#build", "data-picked") == "objects.0"
    page.keyboard.press("ArrowRight")
    assert "Moved object 0" in page.inner_text("#build-status")
    page.locator("#build-details").scroll_into_view_if_needed()
    desktop.shot("axe-workspace-build", full_page=True)
    assert_accessible(page, "workspace build panel", "#editor-panel")


def test_axe_workspace_tabs(desktop, server):
    page = desktop.open("#lessons").page
    run_lesson(page, "bounces", 3)
    assert_accessible(page, "lessons with a lesson open")
    desktop.shot("axe-lessons", full_page=True)
    page.click("#tab-examples")
    page.wait_for_selector("#gallery > *")
    assert_accessible(page, "examples")
    page.click("#tab-grading")
    page.wait_for_selector("#page-grading > *")
    assert_accessible(page, "grading")
    # the example class graded (32 x 24 renders: a few seconds), its table and a student's detail
    enter_token(page, INSTRUCTOR)
    load_example(page)
    page.click("#grade-start")
    page.wait_for_selector("#grade-table", timeout=120_000)
    assert_accessible(page, "grading with a class graded")
    page.click("#grade-table tr[data-student=erin]")
    page.wait_for_selector("#grade-detail:not([hidden])")
    desktop.shot("axe-grading", full_page=True)
    assert_accessible(page, "grading with a student's detail")


# -- the course ---------------------------------------------------------------------------------------


def test_axe_course_dashboard(desktop, server, course):
    desktop.allow.append(r"status of 401")  # the page's first request, before the token is typed
    page = desktop.page
    page.goto(f"{server.url}/course")
    page.wait_for_selector("body[data-ready=true]", state="attached")
    assert_accessible(page, "course without a token")
    page.fill("#course-token", INSTRUCTOR)
    page.dispatch_event("#course-token", "change")
    page.wait_for_function("() => document.querySelector('#course-access-status').dataset.kind === 'ok'")
    assert_accessible(page, "course list")
    page.goto(f"{server.url}/course#{course['id']}")
    page.wait_for_function(
        "() => document.querySelector('#roster-rows tr[data-student=s1]')?.dataset.state === 'graded'"
    )
    page.click("#roster-rows tr[data-student=s1]")
    page.wait_for_selector("#student-detail[data-student=s1] .history-item[data-status=graded]")
    desktop.shot("axe-course-dashboard", full_page=True)
    assert_accessible(page, "course dashboard")


def test_axe_the_student_s_assignment_page(desktop, server, course):
    page = desktop.page
    page.goto(course["students"]["s1"]["link"])
    page.wait_for_selector("body[data-ready=true]", state="attached")
    page.wait_for_selector("#a-sub-list li.a-sub[data-status=graded]")
    desktop.shot("axe-assignment", full_page=True)
    assert_accessible(page, "assignment")
    # the two ray trees at a pixel of the difference map (web/js/course/compare.js)
    img = page.locator("#a-sub-list img[data-picture='error_map.png']")
    page.wait_for_function("(el) => el.complete && el.naturalWidth === 32", arg=img.element_handle())
    img.click()
    page.wait_for_selector("#compare section.compare-side")
    desktop.shot("axe-assignment-compare", full_page=True)
    assert_accessible(page, "assignment with two ray trees compared")


# -- the reference ------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["/reference/", "/reference/scene-format.md"])
def test_axe_reference_pages(desktop, server, path):
    page = desktop.page
    page.goto(f"{server.url}{path}")
    desktop.shot(f"axe-reference-{path.strip('/').replace('/', '-')}")
    assert_accessible(page, f"reference {path}")


# -- courses and LTI ----------------------------------------------------------------------------------


def test_axe_a_student_s_course_page_and_the_courses_panel(desktop, server):
    """/courses/{id} (a course roster's link) and /course's courses panel with its forms (the admin's)."""
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as c:
        assert c.post("/api/courses", json={"id": "axe101", "name": "Accessible Rendering"}).status_code == 201
        r = c.post(
            "/api/courses/axe101/roster", content="id,name,email\nann,Ann,\n", headers={"Content-Type": "text/csv"}
        )
        link = r.json()["students"][0]["link"]
    page = desktop.page
    page.goto(link)
    page.wait_for_selector("#c-status[data-kind=ok]")
    assert_accessible(page, "a student's course page")
    desktop.allow.append(r"status of 401")
    page.goto(f"{server.url}/course")
    page.fill("#course-token", INSTRUCTOR)
    page.dispatch_event("#course-token", "change")
    page.wait_for_selector("#course-list li[data-id=axe101]")
    page.wait_for_selector("#staff-form")
    assert_accessible(page, "the courses panel")


def test_axe_a_refused_lti_launch_page(desktop, server):
    desktop.allow.append(r"status of 400")  # the refusal itself
    page = desktop.page
    page.goto(f"{server.url}/lti/login?iss=https://unknown.example.edu&login_hint=x&target_link_uri=x")
    page.wait_for_selector("main[data-check=platform]")
    assert_accessible(page, "a refused launch")
