"""Courses and their people (server/course/people.py, server/api/routes/courses.py): the server's admin makes
courses and their staff; an instructor publishes into their course and enrols its roster once; a TA follows
the class but may not publish; two courses on one server cannot see each other's students. No render is
needed (workers=0): publishing queues the reference's renders, which nothing here waits for."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import INSTRUCTOR, bearer, course_client, student_token
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
ADMIN = bearer(INSTRUCTOR)


def spec() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


def body(**policy) -> dict:
    return {"spec": spec(), "deadline": (T0 + timedelta(days=2)).isoformat(), **policy}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("courses-data"), T0, workers=0) as c:
        yield c


@pytest.fixture(scope="module")
def two(app):
    """Courses cs101 and cs202, each with an instructor and cs101 with a TA: their tokens."""
    for cid, name in (("cs101", "Rendering I"), ("cs202", "Rendering II")):
        r = app.post("/api/courses", json={"id": cid, "name": name}, headers=ADMIN)
        assert r.status_code == 201, r.text
    people = {}
    for cid, person, role in (
        ("cs101", "prof-a", "instructor"),
        ("cs101", "ta-1", "ta"),
        ("cs202", "prof-b", "instructor"),
    ):
        r = app.post(
            f"/api/courses/{cid}/staff", json={"id": person, "name": person.title(), "role": role}, headers=ADMIN
        )
        assert r.status_code == 201, r.text
        assert r.headers["cache-control"] == "no-store"
        assert r.json()["link"].endswith(f"/course#token={r.json()['token']}")
        people[person] = bearer(r.json()["token"])
    return people


def test_courses_the_admin_creates_courses_and_staff_and_no_one_else_does(app, two):
    r = app.post("/api/courses", json={"id": "cs101", "name": "again"}, headers=ADMIN)
    assert r.status_code == 409
    assert r.json()["errors"][0]["path"] == "id"
    r = app.post("/api/courses", json={"id": "no spaces", "name": "x"}, headers=ADMIN)
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "id"
    r = app.post("/api/courses", json={"id": "cs303", "name": "x"}, headers=two["prof-a"])
    assert r.status_code == 401
    r = app.post("/api/courses/cs101/staff", json={"id": "x", "role": "dean"}, headers=ADMIN)
    assert r.status_code == 422
    assert r.json()["errors"][0]["path"] == "role"
    assert {c["id"] for c in app.get("/api/courses", headers=ADMIN).json()["courses"]} >= {"default", "cs101", "cs202"}
    assert [c["id"] for c in app.get("/api/courses", headers=two["ta-1"]).json()["courses"]] == ["cs101"]


def test_courses_an_instructor_publishes_into_their_course_and_a_ta_is_refused(app, two):
    r = app.post("/api/assignments", json=body(), headers=two["prof-a"])
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    assert app.get("/api/assignments", headers=two["prof-a"]).json()["assignments"][0]["course"] == "cs101"
    r = app.post("/api/courses/cs101/assignments", json=body(), headers=two["ta-1"])
    assert r.status_code == 403
    assert "TA may not publish" in r.json()["errors"][0]["message"]
    r = app.put(f"/api/assignments/{aid}", json=body(), headers=two["ta-1"])
    assert r.status_code == 403
    r = app.post(f"/api/assignments/{aid}/roster", content="id,name,email\nz,Z,\n", headers=two["ta-1"])
    assert r.status_code == 403
    assert "roster" in r.json()["errors"][0]["message"]
    # what a TA may do: follow the class, extend, regrade
    assert app.get(f"/api/assignments/{aid}/dashboard", headers=two["ta-1"]).status_code == 200
    assert app.get(f"/api/assignments/{aid}/grades.csv", headers=two["ta-1"]).status_code == 200
    r = app.post(f"/api/assignments/{aid}/regrade", headers=two["ta-1"])
    assert r.status_code == 200
    assert r.json()["version"] == 2
    # the other course's instructor cannot publish here, nor read it
    r = app.post("/api/courses/cs101/assignments", json=body(), headers=two["prof-b"])
    assert r.status_code == 404  # as an unknown course (test_courses_another_course_answers_as_an_unknown_one)
    assert app.get(f"/api/assignments/{aid}/dashboard", headers=two["prof-b"]).status_code in (401, 404)


def test_courses_a_roster_enrolled_once_holds_across_assignments_with_one_token(app, two):
    r = app.post(
        "/api/courses/cs202/roster", content="id,name,email\nada,Ada,ada@x.edu\nbob,Bob,\n", headers=two["prof-b"]
    )
    assert r.status_code == 200, r.text
    links = {s["id"]: s for s in r.json()["students"]}
    assert links["ada"]["link"].endswith(f"/courses/cs202#token={links['ada']['token']}")
    assert links["ada"]["new"]
    first = app.post("/api/assignments?course=cs202", json=body(), headers=two["prof-b"]).json()["id"]
    second = app.post("/api/courses/cs202/assignments", json=body(), headers=two["prof-b"]).json()["id"]
    ada = bearer(links["ada"]["token"])
    for aid in (first, second):  # on the roster of each, the assignment published after the roster too
        r = app.get(f"/api/assignments/{aid}", headers=ada)
        assert r.status_code == 200
        assert r.json()["student"]["id"] == "ada"
        roster = app.get(f"/api/assignments/{aid}/roster", headers=two["prof-b"]).json()["students"]
        assert [s["id"] for s in roster] == ["ada", "bob"]
    mine = app.get("/api/courses/cs202", headers=ada).json()
    assert mine["you"] == {"id": "ada", "name": "Ada", "role": "student"}
    assert len(mine["assignments"]) == 2
    assert "staff" not in mine
    # the links again: the same tokens (derived), until one is replaced
    again = {s["id"]: s["token"] for s in app.get("/api/courses/cs202/links", headers=two["prof-b"]).json()["students"]}
    assert again == {k: v["token"] for k, v in links.items()}
    r = app.post(f"/api/assignments/{first}/students/ada/link", headers=two["prof-b"])
    assert r.status_code == 200
    assert r.json()["token"] != links["ada"]["token"]
    assert app.get(f"/api/assignments/{second}", headers=ada).status_code == 404  # the old token: nowhere
    assert app.get(f"/api/assignments/{second}", headers=bearer(r.json()["token"])).status_code == 200


def test_courses_two_courses_on_one_server_cannot_see_each_other_s_students(app, two):
    r = app.post("/api/courses/cs101/roster", content="id,name,email\ncyd,Cyd,\n", headers=two["prof-a"])
    cyd = bearer(r.json()["students"][0]["token"])
    theirs = app.post("/api/courses/cs202/assignments", json=body(), headers=two["prof-b"]).json()["id"]
    assert app.get(f"/api/assignments/{theirs}", headers=cyd).status_code == 404
    assert app.get("/api/courses/cs202", headers=cyd).status_code == 404
    r = app.post(f"/api/assignments/{theirs}/submissions", json={"scene": {}}, headers=cyd)
    assert r.status_code == 404
    # the other course's staff see neither its roster nor its students' links
    assert app.get("/api/courses/cs202/roster", headers=two["prof-a"]).status_code == 404
    assert app.get("/api/courses/cs202/links", headers=two["ta-1"]).status_code == 404
    assert "cyd" not in [
        s["id"] for s in app.get("/api/courses/cs202/roster", headers=two["prof-b"]).json()["students"]
    ]


def test_courses_a_staff_link_renewed_stops_the_old_token(app, two):
    r = app.post("/api/courses/cs101/staff", json={"id": "ta-2", "name": "Tee", "role": "ta"}, headers=two["prof-a"])
    assert r.status_code == 201
    old = bearer(r.json()["token"])
    assert app.get("/api/courses/cs101", headers=old).json()["you"]["role"] == "ta"
    r = app.post("/api/courses/cs101/staff/ta-2/link?renew=true", headers=two["prof-a"])
    assert app.get("/api/courses/cs101", headers=old).status_code == 404
    assert app.get("/api/courses/cs101", headers=bearer(r.json()["token"])).json()["you"]["role"] == "ta"
    assert app.post("/api/courses/cs101/staff", json={"id": "x", "role": "ta"}, headers=two["ta-1"]).status_code == 403
    assert app.delete("/api/courses/cs101/staff/ta-2", headers=two["prof-a"]).json()["removed"] is True
    assert app.get("/api/courses/cs101", headers=bearer(r.json()["token"])).status_code == 404


def test_courses_re_issue_all_links_at_once(app, two):
    """POST /api/courses/{id}/links/renew: every student a new link in one request (an assignment's roster only,
    with ?assignment=); the old links stop in every assignment of the course, the others' keep working; a TA may
    not; an assignment of another course is a 404."""
    r = app.post("/api/courses/cs101/roster", content="id,name,email\nre1,Rae,\nre2,Rex,\n", headers=two["prof-a"])
    old = {s["id"]: s["token"] for s in r.json()["students"] if s["id"] in ("re1", "re2")}
    aid = app.post("/api/courses/cs101/assignments", json=body(), headers=two["prof-a"]).json()["id"]
    theirs = app.post("/api/courses/cs202/assignments", json=body(), headers=two["prof-b"]).json()["id"]
    assert app.post("/api/courses/cs101/links/renew", headers=two["ta-1"]).status_code == 403
    r = app.post(f"/api/courses/cs101/links/renew?assignment={theirs}", headers=two["prof-a"])
    assert r.status_code == 404
    assert r.json()["errors"][0]["path"] == "assignment"
    assert all(app.get(f"/api/assignments/{aid}", headers=bearer(t)).status_code == 200 for t in old.values())

    r = app.post(f"/api/courses/cs101/links/renew?assignment={aid}", headers=two["prof-a"])
    assert r.status_code == 200 and r.headers["cache-control"] == "no-store", r.text
    fresh = {s["id"]: s for s in r.json()["students"]}
    assert {"re1", "re2"} <= set(fresh)
    assert all(s["new"] for s in fresh.values())
    for sid, token in old.items():
        assert fresh[sid]["token"] != token
        assert fresh[sid]["link"].endswith(f"/assignments/{aid}#token={fresh[sid]['token']}")
        assert app.get(f"/api/assignments/{aid}", headers=bearer(token)).status_code == 404
        assert app.get("/api/courses/cs101", headers=bearer(token)).status_code == 404
        assert app.get(f"/api/assignments/{aid}", headers=bearer(fresh[sid]["token"])).status_code == 200
    # the links again are the new ones; as CSV too
    again = app.get(f"/api/courses/cs101/links?assignment={aid}", headers=two["prof-a"]).json()["students"]
    assert {s["id"]: s["token"] for s in again} == {k: v["token"] for k, v in fresh.items()}
    r = app.post("/api/courses/cs101/links/renew", headers={**two["prof-a"], "Accept": "text/csv"})
    assert r.status_code == 200
    assert r.text.startswith("id,name,email,link\n")
    assert "re1,Rae,," in r.text
    assert f"#token={fresh['re1']['token']}" not in r.text
    other = app.get("/api/courses/cs202/links", headers=two["prof-b"]).json()["students"]
    assert all(app.get("/api/courses/cs202", headers=bearer(s["token"])).status_code == 200 for s in other)


def test_courses_a_roster_name_loses_control_and_bidi_override_characters_with_a_warning(app, two):
    text = "id,name,email\nfay,Fay\u202egnp.exe,\ngus,Gus\tGrey,\nhal,Hal,\n"
    r = app.post("/api/courses/cs101/roster", content=text.encode(), headers={"Content-Type": "text/csv",
                 **two["prof-a"]})  # fmt: skip
    assert r.status_code == 200, r.text
    got = {s["id"]: s for s in r.json()["students"]}
    assert got["fay"]["name"] == "Faygnp.exe"
    assert got["fay"]["warning"].startswith("line 2.name: 1 control")
    assert got["gus"]["name"] == "Gus Grey"
    assert got["gus"]["warning"].startswith("line 3.name: ")
    assert got["hal"]["name"] == "Hal"
    assert "warning" not in got["hal"]
    names = [s["name"] for s in app.get("/api/courses/cs101/roster", headers=two["prof-a"]).json()["students"]]
    assert not any(c in n for n in names for c in "\u202e\t")


def test_courses_another_course_answers_as_an_unknown_one(app, two):
    """A good token of another course (staff or student), a student's of this one, and no token get the 404 of an
    unknown course on its staff's routes, word for word (course ids are not told, and a good token is not told
    it is not good); a token known nowhere still gets its 401."""
    r = app.post("/api/courses/cs101/roster", content="id,name,email\nemy,Emy,\n", headers=two["prof-a"])
    emy = bearer(r.json()["students"][0]["token"])
    for path in ("roster", "links", "lms/sync"):
        method = app.post if path == "lms/sync" else app.get
        unknown = method(f"/api/courses/nosuch/{path}", headers=two["prof-b"])
        assert unknown.status_code == 404, unknown.text
        for cid, headers in (("cs101", two["prof-b"]), ("cs202", two["ta-1"]), ("cs202", emy), ("cs101", emy),
                             ("cs101", None)):  # fmt: skip
            if headers is None:  # no token (the client sends the admin's unless told otherwise)
                request = app.build_request("POST" if path == "lms/sync" else "GET", f"/api/courses/{cid}/{path}")
                del request.headers["authorization"]
                r = app.send(request)
            else:
                r = method(f"/api/courses/{cid}/{path}", headers=headers)
            assert r.status_code == 404, (cid, path, r.status_code, r.text)
            assert r.json()["errors"][0]["message"].replace(cid, "nosuch") == unknown.json()["errors"][0]["message"]
    assert app.get("/api/courses/cs101/roster", headers=bearer(student_token())).status_code == 401
