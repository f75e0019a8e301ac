"""The instructor's course page (/course: web/course.html, web/js/course/instructor*.js) in a real browser:
the instructor flow of the assignments issue. Uses the fixtures of tests/web/conftest.py (`python -m server` on
loopback with one render worker and an instructor token, typed into the page; Debian's Chromium through
Playwright; a page that fails on console errors it did not expect).

The flow: publish a small assignment from the page (test_dashboard.py's: the example's reference at 32 x 24,
its reference sent as the file the spec names), upload the roster, download the links CSV (each link's token
opens the student's brief), watch the dashboard fill while students submit through the API with their
tokens (rows turn graded with a score, the histogram gets its bars), extend one student's deadline (the
roster shows it at once), read a student's history with their pictures, replace a lost link, export
grades.csv, and publish a regraded version. A bad spec (a misspelled preset) shows the server's error at the
spec's field. Screenshots go to $WEB_SHOTS (default /tmp/web_shots) as course-*.png for a person to look at.
"""

from __future__ import annotations

import base64
import csv
import io
import json
import os
from pathlib import Path
from urllib.parse import urlparse

import httpx

from tests.support.api import INSTRUCTOR, Server, bearer
from tests.support.course_page import CoursePage, open_course, write
from tests.support.dashboard import bad_scene, good_scene, small_reference, small_spec
from tests.support.page import DESKTOP, TEACHER

GRADE_TIMEOUT = 120_000  # ms: a few small renders and their metrics on a busy 2-core machine
ROSTER = [("s1", "Ada Lovelace", "ada@x.edu"), ("s2", "Bob, Jr.", "bob@x.edu"), ("s3", "Cy Young", ""),
          ("s4", "Dee Dee", "dee@x.edu")]  # fmt: skip


def roster_rows(page) -> dict[str, dict]:
    return page.evaluate(
        """() => Object.fromEntries([...document.querySelectorAll('#roster-rows tr[data-student]')].map(tr => [
            tr.dataset.student, {state: tr.dataset.state, extended: tr.dataset.extended,
                                 score: tr.querySelector('td.score').textContent.trim(),
                                 subs: tr.querySelector('td.subs').textContent.trim(),
                                 deadline: tr.querySelector('td.deadline').textContent.trim(),
                                 badges: [...tr.querySelectorAll('.badge')].map(b => b.textContent)}]))"""
    )


def stats(page) -> dict[str, str]:
    return dict(
        page.eval_on_selector_all(
            "#board-stats [data-stat]", "ds => ds.map(d => [d.dataset.stat, d.lastChild.textContent])"
        )
    )


def download(page, selector: str) -> tuple[str, str]:
    with page.expect_download() as info:
        page.click(selector)
    d = info.value
    return d.suggested_filename, Path(d.path()).read_text()


def test_web_course_the_instructor_publishes_rosters_follows_extends_and_exports(browser, server, tmp_path):
    p = open_course(browser, server, tmp_path)
    page = p.page
    page.on("dialog", lambda d: d.accept())  # "replace the link?"
    assert page.get_attribute("#link-docs", "href") == "/reference/assignments.md"

    # -- publish: the spec names its reference as a file, which the form then asks for
    page.set_input_files("#publish-spec", write(tmp_path, "hw0.json", small_spec(inline=False)))
    page.wait_for_selector("#publish-reference", state="visible")
    assert "reference.json" in page.text_content("[data-field=reference] label")
    tests = page.eval_on_selector_all(".af-fb-table tbody tr[data-test]", "rs => rs.map(r => r.dataset.test)")
    assert tests == ["validity", "a glass object", "an area light", "psnr", "pixels"]
    page.set_input_files("#publish-reference", write(tmp_path, "reference.json", small_reference()))
    page.fill("#publish-deadline", "2099-12-08T23:59")
    page.fill("#publish-late_until", "2099-12-09T23:59")
    page.fill("#publish-late_penalty", "0.25")
    page.set_input_files("#publish-starter", write(tmp_path, "starter.json", good_scene()))
    page.fill("#publish-max_submissions", "3")
    page.select_option("#publish-counts", "best")
    page.select_option(".af-fb-table tr[data-test=pixels] select", "after_deadline")
    page.check("#publish-show_reference")
    page.click("#publish button[type=submit]")
    page.wait_for_function("() => /^#[0-9a-f]{32}$/.test(location.hash)")
    aid = page.evaluate("() => location.hash.slice(1)")
    page.wait_for_selector("#h-board")
    assert page.text_content("#h-board") == "HW 0: a small glass ball"
    with httpx.Client(base_url=server.url, timeout=30, headers=TEACHER) as api:
        a = api.get(f"/api/assignments/{aid}").json()
        assert a["deadline"] == "2099-12-09T04:59:00Z"  # 23:59 in New York, sent with its offset (-05:00)
        assert a["policy"]["max_submissions"] == 3
        assert a["policy"]["counts"] == "best"
        assert a["policy"]["show_reference"]
        assert a["policy"]["feedback"]["tests"] == {"pixels": "after_deadline"}
        assert (a["policy"]["late_until"], a["policy"]["late_penalty"]) == ("2099-12-10T04:59:00Z", 0.25)
        assert a["policy"]["starter"] == good_scene()
        assert a["spec"]["reference"]["scene"] == small_reference()  # the file, sent beside the spec
    page.wait_for_function(
        "() => document.querySelector('#reference-grade').textContent === '6 / 6'", timeout=GRADE_TIMEOUT
    )
    assert "No students yet" in page.text_content("#roster-rows")

    # -- the roster, then its links at once (shown this once)
    roster_text = "id,name,email\n" + "".join(f'{i},"{n}",{e}\n' for i, n, e in ROSTER)
    page.set_input_files("#roster-file", write(tmp_path, "roster.csv", roster_text))
    page.wait_for_selector("#links-download")
    assert "Download the links now" in page.text_content("#links-box")
    name, text = download(page, "#links-download")
    assert name == "links-roster.csv"
    links = list(csv.DictReader(io.StringIO(text)))
    assert [(r["id"], r["name"], r["email"]) for r in links] == ROSTER
    tok = {}
    for r in links:
        url = urlparse(r["link"])
        assert (f"{url.scheme}://{url.netloc}", url.path) == (server.url, f"/assignments/{aid}"), r["link"]
        assert url.fragment.startswith("token=")
        tok[r["id"]] = url.fragment.removeprefix("token=")
        brief = httpx.get(f"{server.url}/api/assignments/{aid}", headers=bearer(tok[r["id"]]), timeout=30).json()
        assert brief["student"] == {"id": r["id"], "name": r["name"], "self_declared": False}
    page.wait_for_function("() => document.querySelectorAll('#roster-rows tr[data-student]').length === 4")
    assert {k: v["state"] for k, v in roster_rows(page).items()} == dict.fromkeys(["s1", "s2", "s3", "s4"], "none")
    p.shot("course-roster")

    # -- the class submits through the API while the page is open: the rows fill as they are graded
    with httpx.Client(base_url=server.url, timeout=30) as c:
        png = c.get(f"/api/assignments/{aid}/reference.png", headers=TEACHER).content
        image = {"image": base64.b64encode(png).decode(), "format": "png"}
        for student, body in (("s1", {"scene": good_scene()}), ("s2", {"scene": bad_scene()}), ("s3", image)):
            r = c.post(f"/api/assignments/{aid}/submissions", json=body, headers=bearer(tok[student]))
            assert r.status_code == 202, r.text
    page.wait_for_function(
        """() => { const r = (id) => document.querySelector(`#roster-rows tr[data-student=${id}]`)?.dataset.state;
                   return r('s1') === 'graded' && r('s2') === 'invalid' && r('s3') === 'graded'; }""",
        timeout=GRADE_TIMEOUT,
    )
    rows = roster_rows(page)
    assert {k: (v["score"], v["subs"]) for k, v in rows.items()} == {
        "s1": ("6 / 6", "1"), "s2": ("–", "1"), "s3": ("4 / 4", "1"), "s4": ("–", "0")}  # fmt: skip
    assert rows["s2"]["badges"] == ["invalid only"]
    assert rows["s4"]["badges"] == ["not submitted"]
    assert stats(page) == {"students": "4", "submitted": "3", "graded": "2", "waiting": "0", "not_submitted": "1",
                           "invalid": "1", "late": "0", "mean": "6 / 6", "median": "6 / 6"}  # fmt: skip
    bars = page.eval_on_selector_all("#histogram-svg .bar", "gs => gs.map(g => Number(g.dataset.count))")
    assert bars == [0] * 9 + [2]  # both in the top tenth
    page.select_option("#roster-filter", "none")
    assert list(roster_rows(page)) == ["s4"]
    page.select_option("#roster-filter", "all")

    # -- an extension for s4, shown in the roster at once
    page.click("#roster-rows tr[data-student=s4]")
    page.wait_for_selector("#student-detail:not([hidden]) #ext-deadline")
    assert "Nothing submitted yet" in page.text_content("#student-detail")
    page.fill("#ext-deadline", "2099-12-15T12:00")
    page.click("#ext-grant")
    page.wait_for_function(
        "() => document.querySelector('#roster-rows tr[data-student=s4]').dataset.extended === 'true'"
    )
    assert "extended" in roster_rows(page)["s4"]["badges"] and "Dec 15" in roster_rows(page)["s4"]["deadline"]
    ext = httpx.get(f"{server.url}/api/assignments/{aid}/roster", headers=TEACHER, timeout=30).json()["students"]
    assert {s["id"]: s for s in ext}["s4"]["deadline"] == "2099-12-15T17:00:00Z"  # noon in New York

    # -- s1's detail: their history with the feedback and pictures (fetched with the instructor's header)
    page.click("#roster-rows tr[data-student=s1]")
    page.wait_for_selector("#student-detail[data-student=s1] .history-item[data-status=graded]")
    page.wait_for_function(
        """() => { const imgs = [...document.querySelectorAll('#student-detail .history-item img')];
                   return imgs.length === 4
                       && imgs.every(i => i.complete && i.naturalWidth > 0 && i.src.startsWith('blob:')); }"""
    )
    tests = page.eval_on_selector_all(
        "#student-detail .grade-test", "ls => ls.map(l => [l.dataset.test, l.dataset.status])"
    )
    assert tests == [["validity", "passed"], ["a glass object", "passed"], ["an area light", "passed"],
                     ["psnr", "passed"], ["pixels", "passed"]]  # fmt: skip
    name, text = download(page, "#student-detail [data-results]")
    assert json.loads(text)["score"] == 6 and name == "results-s1-1.json"
    p.shot("course-detail")
    assert page.evaluate("() => location.hash") == f"#{aid}/s1"  # a link to this detail: opened again by a reload
    page.reload()  # (the token is kept in this browser)
    page.wait_for_selector("#student-detail[data-student=s1] .history-item[data-status=graded]")
    assert page.input_value("#course-token") == INSTRUCTOR
    page.click("#student-close")
    page.evaluate("() => window.scrollTo(0, 0)")
    p.shot("course-dashboard", full_page=True)

    # -- a lost link replaced: the old token stops working
    page.click("#roster-rows tr[data-student=s2]")
    page.click("#btn-new-link")
    page.wait_for_selector("#new-link .course-link button.copy")
    new = urlparse(page.text_content("#new-link code")).fragment.removeprefix("token=")
    assert new
    assert new != tok["s2"]
    assert httpx.get(f"{server.url}/api/assignments/{aid}", headers=bearer(tok["s2"]), timeout=30).status_code == 404
    assert httpx.get(f"{server.url}/api/assignments/{aid}", headers=bearer(new), timeout=30).status_code == 200

    # -- grades.csv, downloaded with the instructor's header
    name, text = download(page, "#export-grades")
    assert name == "grades.csv"
    got = [
        (r["id"], r["score"], r["max_score"], r["late"], r["submissions"]) for r in csv.DictReader(io.StringIO(text))
    ]
    assert got == [("s1", "6", "6", "false", "1"), ("s2", "", "", "", "1"), ("s3", "4", "4", "false", "1"),
                   ("s4", "", "", "", "0")]  # fmt: skip
    name, text = download(page, "#export-gradebook")
    assert name == "gradebook.csv"
    assert text.splitlines()[1].startswith("Points Possible")

    # -- regrade: an edited spec published as version 2 with ?regrade=true; s1's grade follows it
    edited = small_spec(inline=True)
    edited["reference"]["pixels"]["points"] = 4
    page.click("#edit-box summary")
    page.set_input_files("#edit-box input[name=spec]", write(tmp_path, "hw0-v2.json", edited))
    assert page.is_checked("#edit-box input[id$=-regrade]")
    assert page.input_value("#edit-box input[name=deadline]") == "2099-12-08T23:59"  # the policy kept
    assert page.input_value("#edit-box input[name=late_until]") == "2099-12-09T23:59"
    assert page.input_value("#edit-box tr[data-test=pixels] select") == "after_deadline"
    page.click("#edit-box button[type=submit]")
    page.wait_for_function("() => document.querySelectorAll('#versions li').length === 2")
    page.wait_for_function(
        "() => document.querySelector('#roster-rows tr[data-student=s1] td.score').textContent.trim() === '8 / 8'",
        timeout=GRADE_TIMEOUT,
    )
    a = httpx.get(f"{server.url}/api/assignments/{aid}", headers=TEACHER, timeout=30).json()
    assert a["version"] == 2
    assert a["policy"]["max_submissions"] == 3
    assert a["policy"]["late_penalty"] == 0.25
    assert a["policy"]["starter"] == good_scene() and a["policy"]["feedback"]["tests"] == {"pixels": "after_deadline"}
    p.context.close()
    assert p.unexpected_errors() == []


def test_web_course_a_bad_spec_shows_the_servers_error_at_its_field(browser, server, tmp_path):
    p = open_course(browser, server, tmp_path)
    page = p.page
    bad = small_spec(inline=True)
    bad["requirements"][1]["check"] = "area_ligth"
    page.click("#publish button[type=submit]")  # nothing picked: the page says what is missing, at the fields
    assert "pick the spec file" in page.text_content("#publish-spec-err")
    assert "deadline is required" in page.text_content("#publish-deadline-err")
    page.set_input_files("#publish-spec", write(tmp_path, "bad.json", bad))
    assert page.is_hidden("[data-field=reference]")  # the reference is inline
    page.fill("#publish-deadline", "2099-12-08T23:59")
    p.allow.append(r"422")  # the browser logs the refused request
    page.click("#publish button[type=submit]")
    page.wait_for_selector("#publish-spec-err li")
    err = page.text_content("#publish-spec-err")
    assert "spec.requirements[1].check" in err
    assert "did you mean 'area_light'" in err
    assert page.get_attribute("#publish-spec", "aria-invalid") == "true"
    assert page.text_content("#publish-deadline-err") == ""
    assert "see the fields marked" in page.text_content("#publish .af-status")
    assert page.evaluate("() => location.hash") == ""
    p.shot("course-bad-spec", full_page=True)

    # the spec fixed, the assignment is published; a roster with a wrong header is refused, saying why
    page.set_input_files("#publish-spec", write(tmp_path, "good.json", small_spec(inline=True)))
    page.click("#publish button[type=submit]")
    page.wait_for_selector("#h-board")
    page.set_input_files("#roster-file", write(tmp_path, "roster.csv", "name,id,email\nAda,s1,\n"))
    page.wait_for_selector("#roster-errors li")
    assert "expected the header 'id,name,email'" in page.text_content("#roster-errors")
    assert page.get_attribute("#roster-file", "aria-invalid") == "true"
    assert page.is_hidden("#links-box")
    assert "No students yet" in page.text_content("#roster-rows")
    p.context.close()
    assert p.unexpected_errors() == []


def variant(change: str) -> dict:
    """The reference scene with one thing changed: scores spread over the points."""
    scene = good_scene()
    if change == "no glass":
        scene["materials"]["glass"] = {"kd": 0.8}
    elif change == "blue ball":
        scene["materials"]["red"]["kd"] = [0.1, 0.2, 0.8]
    elif change == "point light":
        scene["lights"] = [{"type": "point", "position": [0, 3.5, 0], "intensity": 9}]
    return scene


def test_web_course_a_class_of_300_fills_the_dashboard(browser, server, tmp_path):
    """300 students on the roster, 24 of them submitting scenes of varied quality through the API while the
    page is open: every row is shown, the graded ones with their scores, the histogram spread over them;
    the filter and the sort work on the whole class. Screenshots for a person to look at."""
    with httpx.Client(base_url=server.url, timeout=60, headers=TEACHER) as api:
        body = {"spec": small_spec(), "deadline": "2099-12-08T23:59:00Z", "counts": "last", "open": True}
        aid = api.post("/api/assignments", json=body).json()["id"]
        text = "id,name,email\n" + "".join(f"st{i:03d},Student {i},st{i}@x.edu\n" for i in range(300))
        r = api.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv"})
        tok = [s["token"] for s in r.json()["students"]]
        zoe = api.post(f"/api/assignments/{aid}/join", json={"name": "Zoë Z"}).json()["id"]  # one more, by a name
    p = open_course(browser, server, tmp_path)
    page = p.page
    page.evaluate(f"() => (location.hash = '{aid}')")
    page.wait_for_function("() => document.querySelectorAll('#roster-rows tr[data-student]').length === 301")
    assert "self-declared" in roster_rows(page)[zoe]["badges"]
    assert [k for k, v in roster_rows(page).items() if "self-declared" in v["badges"]] == [zoe]
    changes = ["good", "no glass", "blue ball", "point light", "bad"] * 4 + ["good"] * 4
    with httpx.Client(base_url=server.url, timeout=60) as c:
        for i, change in enumerate(changes):
            scene = bad_scene() if change == "bad" else variant(change)
            r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(tok[i * 7]))
            assert r.status_code == 202, r.text
    page.wait_for_function("() => document.querySelectorAll('#roster-rows tr:not([data-state=none])').length === 24")
    page.wait_for_function(
        """() => document.querySelectorAll('#roster-rows tr[data-state=graded]').length === 20
                  && document.querySelectorAll('#roster-rows tr[data-state=invalid]').length === 4""",
        timeout=GRADE_TIMEOUT * 2,
    )
    s = stats(page)
    counts = (s["students"], s["submitted"], s["graded"], s["invalid"], s["not_submitted"])
    assert counts == ("301", "24", "20", "4", "277")
    bars = page.eval_on_selector_all("#histogram-svg .bar", "gs => gs.map(g => Number(g.dataset.count))")
    assert sum(bars) == 20 and bars[-1] >= 8 and sum(1 for b in bars if b) >= 2, bars  # spread, the good ones on top
    page.click("#roster-table th[data-col=score] button")  # the best first
    first = page.eval_on_selector_all("#roster-rows tr[data-student]", "rs => rs.slice(0, 8).map(r => r.dataset.state)")
    assert first == ["graded"] * 8
    page.select_option("#roster-filter", "graded")
    assert len(roster_rows(page)) == 20
    page.select_option("#roster-filter", "all")
    page.click("#roster-table th[data-col=student] button")
    page.evaluate("() => window.scrollTo(0, 0)")
    p.shot("course-class")
    page.set_viewport_size({"width": 1024, "height": 768})  # a laptop's width
    p.shot("course-class-1024", full_page=False)
    p.context.close()
    assert p.unexpected_errors() == []


def test_web_course_on_loopback_without_a_token_everyone_is_the_instructor(browser, tmp_path):
    """A server on loopback with no TRACER_INSTRUCTOR_TOKEN: the page answers without a token and says why."""
    env = {k: v for k, v in os.environ.items() if k != "TRACER_INSTRUCTOR_TOKEN"}
    with Server(tmp_path / "data", workers=0, env=env) as own:
        p = CoursePage(browser, own, DESKTOP)
        try:
            p.page.goto(f"{own.url}/course")
            p.page.wait_for_selector("body[data-ready=true]", state="attached")
            p.page.wait_for_function("() => document.querySelector('#course-access-status').dataset.kind === 'ok'")
            assert "everyone who reaches it is the instructor" in p.page.text_content("#course-access-status")
            assert "None yet" in p.page.text_content("#list-status")
        finally:
            p.context.close()
        assert p.unexpected_errors() == []


def test_web_course_links_again_and_re_issued(browser, server, tmp_path):
    """The links shown after an upload are not lost with the page: "Download links again" gives the same links
    (GET /api/courses/{cid}/links: they still work); "Re-issue all…" asks first, saying the old links stop
    working, and a dismissed question changes nothing; accepted, every student gets a new link and the old ones
    are refused."""
    deadline = "2099-12-08T23:59:00Z"
    r = httpx.post(f"{server.url}/api/assignments", json={"spec": small_spec(inline=True), "deadline": deadline},
                   headers=TEACHER, timeout=30)  # fmt: skip
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    roster = "id,name,email\nr1,Rae One,r1@x.edu\nr2,Rex Two,\n"
    r = httpx.post(f"{server.url}/api/assignments/{aid}/roster", content=roster,
                   headers={**TEACHER, "Content-Type": "text/csv"}, timeout=30)  # fmt: skip
    sent = {st["id"]: st["link"] for st in r.json()["students"]}
    p = open_course(browser, server, tmp_path)  # a new page: the links of the upload are not on it
    page = p.page
    page.goto(f"{server.url}/course#{aid}")
    page.wait_for_function("() => document.querySelectorAll('#roster-rows tr[data-student]').length === 2")
    assert page.is_hidden("#links-box")

    name, text = download(page, "#links-again")
    again = {row["id"]: row["link"] for row in csv.DictReader(io.StringIO(text))}
    assert name == "links-again.csv"
    assert again == sent
    assert "They still work" in page.text_content("#links-box")
    p.shot("course-links-again")

    asked = []
    page.once("dialog", lambda d: (asked.append(d.message), d.dismiss()))
    page.click("#links-reissue")
    assert asked and "stop working" in asked[0] and "Re-issue all 2 links" in asked[0], asked
    token = {sid: urlparse(link).fragment.removeprefix("token=") for sid, link in sent.items()}

    def brief(t: str) -> httpx.Response:
        return httpx.get(f"{server.url}/api/assignments/{aid}", headers=bearer(t), timeout=30)

    assert all(brief(t).status_code == 200 for t in token.values())  # dismissed: nothing changed

    page.once("dialog", lambda d: d.accept())
    page.click("#links-reissue")
    page.wait_for_function("() => document.querySelector('#roster-status').dataset.kind === 'ok'")
    name, text = download(page, "#links-download")
    fresh = {
        row["id"]: urlparse(row["link"]).fragment.removeprefix("token=") for row in csv.DictReader(io.StringIO(text))
    }
    assert name == "links-reissued.csv"
    assert set(fresh) == {"r1", "r2"}
    assert all(brief(t).status_code == 404 for t in token.values())
    assert all(brief(t).status_code == 200 for t in fresh.values())
    assert "no longer work" in page.text_content("#links-box")
    p.shot("course-links-reissued")
    p.context.close()
    assert p.unexpected_errors() == []
