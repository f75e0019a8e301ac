"""A course in an LMS, end to end (server/course/lms.py over server/lti/): a test platform on loopback
(tests/lti_platform.py: its own keys, JWKS, token endpoint, AGS line items, NRPS) and the service on loopback
(uvicorn, one render worker). The whole path with real signed JWTs: the instructor adds the tool by Deep
Linking and picks an assignment, a student launches it and lands on the assignment with their token, submits,
is graded, and the score goes back to the LMS; while the LMS is down the score waits (shown pending on the
dashboard) and goes once it is back; the roster comes from NRPS page by page. The app's clock is a `Clock`
(deadlines and retries follow it); the launches' own times are the platform's real ones."""

from __future__ import annotations

import re
from datetime import timedelta

import httpx
import pytest

from server.course.lms_store import (
    LmsStore,
    LtiContextRow,
    LtiLinkRow,
    LtiPickRow,
    LtiScoreRow,
    RefusedScore,
)
from tests.support.api import bearer, wait_for
from tests.support.lms import ADMIN, EXAMPLE, NRPS, T0
from tests.support.lti_platform import INSTRUCTOR as LMS_INSTRUCTOR
from tests.support.lti_platform import LEARNER


def test_lms_deep_link_launch_submit_and_the_grade_goes_back_even_after_the_lms_was_down(tool, lms):
    url, app, client = tool
    p, aid = lms
    # the instructor adds the tool: the picker lists the course's assignments
    members = {"context_memberships_url": f"{p.url}/memberships/course-1?limit=2", "service_versions": ["2.0"]}
    r = p.do_launch(client, url, sub="teacher-1", roles=[LMS_INSTRUCTOR], message_type="LtiDeepLinkingRequest",
                    overrides={NRPS: members})  # fmt: skip
    assert r.status_code == 200 and "Pick an assignment" in r.text and aid in r.text, r.text
    pick = re.search(r'name="pick" value="([^"]+)"', r.text)[1]
    r = client.post("/lti/pick", data={"pick": pick, "assignment": aid})
    assert r.status_code == 200, r.text
    assert f'action="{p.url}/deep_link_return"' in r.text
    assert "form-action" in r.headers["content-security-policy"]
    csp = r.headers["content-security-policy"]  # the return page is framed by the LMS's own pages only
    assert f"frame-ancestors {p.url};" in csp and "frame-ancestors *" not in csp, csp
    jwt = re.search(r'name="JWT" value="([^"]+)"', r.text)[1]
    assert httpx.post(p.url + "/deep_link_return", data={"JWT": jwt}).status_code == 200  # verified by the LMS
    item = p.deep_links[-1]["https://purl.imsglobal.org/spec/lti-dl/claim/content_items"][0]
    assert item["custom"] == {"assignment": aid}
    assert item["lineItem"]["scoreMaximum"] == 13
    assert p.deep_links[-1]["https://purl.imsglobal.org/spec/lti-dl/claim/data"] == "opaque-data-1"
    assert client.post("/lti/pick", data={"pick": pick, "assignment": aid}).status_code == 400  # used once

    # a student launches the link: their assignment, with their token in the fragment; the same at every launch
    r = p.do_launch(client, url, sub="student-7", roles=[LEARNER], custom={"assignment": aid})
    assert r.status_code == 303, r.text
    where, token = r.headers["location"].split("#token=")
    assert where == f"/assignments/{aid}"
    assert all("Max-Age=0" in c for c in r.headers.get_list("set-cookie"))  # no session cookie: only the state's, ended
    again = p.do_launch(client, url, sub="student-7", roles=[LEARNER], custom={"assignment": aid})
    assert again.headers["location"].split("#token=")[1] == token
    brief = client.get(f"/api/assignments/{aid}", headers=bearer(token)).json()
    assert brief["student"] == {"id": "ada", "name": "Ada Lovelace", "self_declared": False}

    # the LMS is down when the grade is made: the score waits, shown pending
    p.down = True
    scene = (EXAMPLE / "class" / "alice.json").read_text()
    r = client.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(token))
    assert r.status_code == 202, r.text
    sub = r.headers["location"]
    graded = wait_for(lambda: (s := client.get(sub, headers=bearer(token)).json())["status"] == "graded" and s,
                      300, "the submission's grade", 0.5)  # fmt: skip
    store = LmsStore(app.state.settings.data_dir)
    wait_for(lambda: store.scores(aid)["error"], 60, "a failed post of the score", 0.2)
    board = client.get(f"/api/assignments/{aid}/dashboard", headers=ADMIN).json()
    assert board["lms"]["grades"]["pending"] == 1 and "503" in board["lms"]["grades"]["error"], board["lms"]
    assert p.scores == []
    # back: the next try (after its wait, on the app's clock) sends it
    p.down = False
    app.state.clock.now = T0 + timedelta(hours=2)
    app.state.lms.poster.wake()
    wait_for(lambda: p.scores, 60, "the score at the LMS", 0.2)
    (score,) = p.scores
    assert score["userId"] == "student-7" and score["scoreGiven"] == pytest.approx(graded["score"])
    assert score["scoreMaximum"] == 13
    assert score["lineitem"] == "li-1"
    assert (score["activityProgress"], score["gradingProgress"]) == ("Completed", "FullyGraded")
    board = client.get(f"/api/assignments/{aid}/dashboard", headers=ADMIN).json()
    assert (board["lms"]["grades"]["pending"], board["lms"]["grades"]["sent"]) == (0, 1)

    # a staff-graded item (server/course/manual.py): its grade goes back only once released, with the auto part
    spec = client.get(f"/api/assignments/{aid}", headers=ADMIN).json()["spec"]
    spec["manual"] = [{"name": "creativity", "points": 2, "rubric": [{"name": "new objects", "points": 1.5}]}]
    body = {"spec": spec, "deadline": (T0 + timedelta(days=2)).isoformat()}
    assert client.put(f"/api/assignments/{aid}", json=body, headers=ADMIN).status_code == 200
    put = f"{sub}/manual/creativity"
    assert client.put(put, json={"rubric": ["new objects"]}, headers=ADMIN).status_code == 200
    poster = app.state.lms.poster
    assert poster.sweep() == 0 and len(p.scores) == 1  # not released: the same total, nothing new to send
    assert client.post(f"/api/assignments/{aid}/release", headers=ADMIN).status_code == 200
    poster.wake()
    wait_for(lambda: len(p.scores) == 2, 60, "the released total at the LMS", 0.2)
    assert p.scores[1]["scoreGiven"] == pytest.approx(graded["score"] + 1.5) and p.scores[1]["scoreMaximum"] == 15


def test_lms_the_roster_comes_from_nrps_page_by_page_and_the_dashboard_shows_who_has_not_submitted(tool, lms):
    url, app, client = tool
    p, aid = lms
    members = {"context_memberships_url": f"{p.url}/memberships/course-1?limit=2", "service_versions": ["2.0"]}
    r = p.do_launch(client, url, sub="teacher-1", roles=[LMS_INSTRUCTOR], custom={"assignment": aid},
                    overrides={NRPS: members})  # fmt: skip
    assert r.status_code == 303
    assert r.headers["location"].startswith("/course#token=")
    r = client.post("/api/courses/gfx/lms/sync", headers=ADMIN)
    assert r.status_code == 200 and r.json()["members"] == 4, r.text  # 5 members on 3 pages, one the instructor
    board = client.get(f"/api/assignments/{aid}/dashboard", headers=ADMIN).json()
    states = {s["id"]: s["state"] for s in board["students"]}
    assert {f"sis-{i}" for i in range(1, 5)} <= set(states)
    assert all(states[f"sis-{i}"] == "none" for i in range(1, 5))
    assert board["lms"]["roster_synced_at"] is not None
    # the instructor's own launch made them the course's instructor; the sync, the LMS's instructor (sis-0) too
    staff = client.get("/api/courses/gfx/staff", headers=ADMIN).json()["staff"]
    assert {s["id"]: s["role"] for s in staff} == {"ada": "instructor", "sis-0": "instructor"}, staff
    # each in the course's audit trail as the LMS's doing (server/course/audit.py)
    events = client.get("/api/courses/gfx/audit", params={"limit": 500}, headers=ADMIN).json()["events"]
    synced = {e["target"]["student"] for e in events if (e["action"], e["why"]) == ("student.add", "LMS roster sync")}
    assert {f"sis-{i}" for i in range(1, 5)} <= synced
    assert all(e["who"] == "lms" for e in events if e["why"].startswith("LMS"))
    assert any(e["action"] == "staff.add" and e["after"]["role"] == "instructor" and e["who"] == "lms" for e in events)


def test_lms_a_student_of_a_course_no_instructor_opened_is_told_so(tool, lms):
    url, app, client = tool
    p, _ = lms
    r = p.do_launch(client, url, sub="student-9", roles=[LEARNER], context={"id": "course-2", "title": "Other"})
    assert r.status_code == 403
    assert "not set up yet" in r.text
    assert all("Max-Age=0" in c for c in r.headers.get_list("set-cookie"))


def test_lms_scores_keep_strictly_increasing_timestamps_and_a_newer_one_supersedes_an_unsent_one(tmp_path):
    store = LmsStore(tmp_path)
    row = {"platform_id": "p", "lineitem": "L", "user_id": "u", "assignment_id": "a", "student": "s",
           "score_given": 5.0, "score_max": 13.0}  # fmt: skip
    assert store.add_score(row, 100.0) and not store.add_score(row, 100.0)  # the same numbers: nothing new
    assert store.add_score({**row, "score_given": 7.0}, 100.0)  # the same second: 1 ms later
    due = store.due(100.0, 10)
    assert [(d["score_given"], d["timestamp"]) for d in due] == [(7.0, 100.001)]


def test_lms_rows_are_typed_with_every_column_of_their_tables(tmp_path):
    """`LtiContextRow`, `LtiLinkRow`, `LtiPickRow` and `LtiScoreRow` (server/course/lms_store.py) name each column
    of their tables and no other, and the store's reads return exactly those keys; `RefusedScore` those of a
    refusal (`next_try` as `at`), so that the type checker knows the keys the LMS side and the poster read."""
    store = LmsStore(tmp_path)
    tables = (("course_lti_contexts", LtiContextRow), ("course_lti_links", LtiLinkRow),
              ("course_lti_picks", LtiPickRow), ("course_lti_scores", LtiScoreRow))  # fmt: skip
    for table, row in tables:
        columns = {r["name"] for r in store.db.execute(f"PRAGMA table_info({table})")}
        assert set(row.__required_keys__) == columns, table
    store.link_context("p", "ctx", "gfx", "Graphics", 1.0)
    assert set(store.context("p", "ctx")) == set(LtiContextRow.__required_keys__)
    assert [set(c) for c in store.contexts("gfx")] == [set(LtiContextRow.__required_keys__)]
    store.keep_link("p", "link-1", "gfx", "a" * 32, "L", 1.0)
    assert set(store.link("p", "link-1")) == set(LtiLinkRow.__required_keys__)
    assert [set(x) for x in store.links("a" * 32)] == [set(LtiLinkRow.__required_keys__)]
    pick = store.new_pick({"platform_id": "p", "deployment_id": "d", "course_id": "gfx", "settings": "",
                           "resource_link_id": "link-1", "expires": 100.0})  # fmt: skip
    assert set(store.take_pick(pick, 1.0)) == set(LtiPickRow.__required_keys__)
    row = {"platform_id": "p", "lineitem": "L", "user_id": "u", "assignment_id": "a" * 32, "student": "s",
           "score_given": 5.0, "score_max": 13.0}  # fmt: skip
    assert store.add_score(row, 1.0)
    assert set(store.last_score("L", "u")) == set(LtiScoreRow.__required_keys__)
    due = store.due(1.0, 10)
    assert [set(d) for d in due] == [set(LtiScoreRow.__required_keys__)]
    store.refused(due[0]["id"], 422, "no such user", 2.0)
    refusals = store.refusals("a" * 32)
    assert [set(r) for r in refusals] == [set(RefusedScore.__required_keys__)]
    assert (refusals[0]["status"], refusals[0]["at"]) == (422, 2.0)


def test_lms_a_link_with_no_assignment_opens_a_student_s_course_page_and_an_instructor_s_picker(tool, lms):
    """A course navigation link (or an assignment link made without deep linking) names no assignment: the
    student gets their course's page (the assignments they are on), the instructor the picker that binds it."""
    url, app, client = tool
    p, aid = lms
    nav = {"id": "nav-1", "title": "Ray tracing"}
    r = p.do_launch(client, url, sub="student-7", roles=[LEARNER], resource_link=nav)
    assert r.status_code == 303 and r.headers["location"].startswith("/courses/gfx#token="), r.text
    token = r.headers["location"].split("#token=")[1]
    assert [a["id"] for a in client.get("/api/courses/gfx", headers=bearer(token)).json()["assignments"]] == [aid]
    r = p.do_launch(client, url, sub="teacher-1", roles=[LMS_INSTRUCTOR], resource_link=nav)
    assert r.status_code == 200
    assert "Pick an assignment for this link" in r.text
    pick = re.search(r'name="pick" value="([^"]+)"', r.text)[1]
    assert client.post("/lti/pick", data={"pick": pick, "assignment": aid}).status_code == 200
    r = p.do_launch(client, url, sub="student-7", roles=[LEARNER], resource_link=nav)  # bound now
    assert r.headers["location"].startswith(f"/assignments/{aid}#token=")


def test_lms_a_link_without_a_line_item_gets_a_gradebook_column_once(tool, lms):
    """A launch whose AGS claim has `lineitems` but no `lineitem` (a link made without deep linking): the tool
    asks for the link's column, makes one of the assignment's points when there is none, and keeps it."""
    url, app, client = tool
    p, aid = lms
    ags = {"https://purl.imsglobal.org/spec/lti-ags/claim/endpoint": {
        "scope": ["https://purl.imsglobal.org/spec/lti-ags/scope/lineitem",
                  "https://purl.imsglobal.org/spec/lti-ags/scope/score"],
        "lineitems": f"{p.url}/lineitems?context=course-1"}}  # fmt: skip
    link = {"id": "link-2", "title": "HW 4 again"}
    before = len(p.line_items)
    for _ in range(2):
        r = p.do_launch(client, url, sub="student-7", roles=[LEARNER], resource_link=link,
                        custom={"assignment": aid}, overrides=ags)  # fmt: skip
        assert r.status_code == 303, r.text
    made = [i for i in p.line_items.values() if i.get("resourceLinkId") == "link-2"]
    assert len(p.line_items) == before + 1
    assert len(made) == 1  # made once, found again at the second launch
    assert made[0]["scoreMaximum"] == 13
    assert made[0]["resourceId"] == aid
    assert LmsStore(app.state.settings.data_dir).link(p.registered_id, "link-2")["lineitem"] == made[0]["id"]


def test_lms_an_email_is_no_identity_unless_the_platform_is_trusted_with_emails(tool, lms):
    """A learner's launch whose email is an unlinked roster student's does not get that student's token: the
    roster link, given once while launched, links them (a good one of an unlinked student of the course only).
    A platform registered with trust_emails links by the email at once."""
    url, app, client = tool
    p, aid = lms
    text = "id,name,email\nzed,Zed Z,zed@example.edu\nyan,Yan Y,yan@example.edu\nxia,Xia X,xia@example.edu\n"
    r = client.post("/api/courses/gfx/roster", content=text, headers={"Content-Type": "text/csv", **ADMIN})
    assert r.status_code == 200, r.text
    links = {s["id"]: s["link"] for s in r.json()["students"]}
    r = p.do_launch(client, url, sub="mallory", roles=[LEARNER], custom={"assignment": aid},
                    overrides={"email": "zed@example.edu"})  # fmt: skip
    assert r.status_code == 200 and "Link your course account" in r.text and "token=" not in r.text, r.text
    assert "location" not in r.headers
    claim = re.search(r'name="claim" value="([^"]+)"', r.text)[1]
    r = client.post("/lti/claim", data={"claim": claim, "link": "https://x/courses/gfx#token=" + "A" * 43})
    assert r.status_code == 403  # not a roster link: and the form is used up
    assert client.post("/lti/claim", data={"claim": claim, "link": links["zed"]}).status_code == 400
    r = p.do_launch(client, url, sub="student-z", roles=[LEARNER], custom={"assignment": aid},
                    overrides={"email": "zed@example.edu"})  # fmt: skip
    claim = re.search(r'name="claim" value="([^"]+)"', r.text)[1]
    r = client.post("/lti/claim", data={"claim": claim, "link": links["zed"]})
    assert r.status_code == 200 and "Linked: Zed Z" in r.text, r.text
    r = p.do_launch(client, url, sub="student-z", roles=[LEARNER], custom={"assignment": aid},
                    overrides={"email": "zed@example.edu"})  # fmt: skip
    assert r.status_code == 303
    assert (r.headers["location"] == f"/assignments/{aid}#token=" + links["zed"].split(
        "#token=")[1])  # fmt: skip
    # the roster read from the LMS leaves a member of a roster student's email to their own launch
    p.members["course-1"].append({"status": "Active", "name": "Xia from the LMS", "email": "xia@example.edu",
                                  "user_id": "user-xia", "roles": [LEARNER]})  # fmt: skip
    try:
        r = client.post("/api/courses/gfx/lms/sync", headers=ADMIN)
        assert r.status_code == 200 and r.json()["unlinked"] == 1, r.text
    finally:
        p.members["course-1"].pop()
    roster = client.get("/api/courses/gfx/roster", headers=ADMIN).json()["students"]
    assert [s["id"] for s in roster if s["email"] == "xia@example.edu"] == ["xia"]
    # a platform trusted with its emails
    body = {**p.registration(trust_emails=True), "deployment_ids": [p.deployment_id]}
    assert client.post("/api/lti/platforms", json=body, headers=ADMIN).json()["trust_emails"] is True
    try:
        r = p.do_launch(client, url, sub="student-y", roles=[LEARNER], custom={"assignment": aid},
                        overrides={"email": "yan@example.edu"})  # fmt: skip
        assert r.status_code == 303
        assert r.headers["location"].split("#token=")[1] == links["yan"].split("#token=")[1]
    finally:
        body["trust_emails"] = False
        assert client.post("/api/lti/platforms", json=body, headers=ADMIN).json()["trust_emails"] is False


def test_lms_a_score_the_lms_refuses_for_good_is_failed_shown_with_why_and_sent_again_by_staff(tool, lms):
    """A 4xx other than 401/429 (the same post would be refused again) is not tried again: the row is failed with
    the LMS's status and message, the dashboard lists it, and "send again" queues it once the LMS is fixed. The
    score's comment goes as AGS's `comment`."""
    url, app, client = tool
    p, aid = lms
    lms_ = app.state.lms
    row = {"platform_id": p.registered_id, "lineitem": f"{p.url}/lineitems/li-1", "user_id": "refused-1",
           "assignment_id": aid, "student": "refused-1", "score_given": 9.0, "score_max": 13.0,
           "comment": "Good shadows; the glass is too dark."}  # fmt: skip
    p.refuse = (422, "invalid_score")
    try:
        assert lms_.store.add_score(row, lms_.now())
        lms_.poster.wake()
        wait_for(lambda: lms_.store.scores(aid)["failed"], 60, "the refused score marked failed", 0.2)
        board = client.get(f"/api/assignments/{aid}/dashboard", headers=ADMIN).json()["lms"]["grades"]
        (refused,) = board["refused"]
        assert refused["student"] == "refused-1" and refused["status"] == 422, refused
        assert "HTTP 422" in refused["error"] and "invalid_score" in refused["error"], refused
        # not tried again, however late it gets (a pending row would be, after its wait)
        app.state.clock.now += timedelta(days=3)
        lms_.poster.post_due()
        assert lms_.store.scores(aid)["failed"] == 1 and not [s for s in p.scores if s["userId"] == "refused-1"]
        # the same score again is not kept anew (it would be refused again): staff send it again instead
        assert not lms_.store.add_score(row, lms_.now())
    finally:
        p.refuse = None
    assert (
        client.post(f"/api/assignments/{aid}/lms/send-again", json={"score": 999999}, headers=ADMIN).status_code == 404
    )
    r = client.post(f"/api/assignments/{aid}/lms/send-again", headers=ADMIN)
    assert r.status_code == 200 and r.json()["queued"] == 1 and r.json()["grades"]["refused"] == [], r.text
    wait_for(lambda: [s for s in p.scores if s["userId"] == "refused-1"], 60, "the score sent again", 0.2)
    (sent,) = [s for s in p.scores if s["userId"] == "refused-1"]
    assert sent["scoreGiven"] == 9.0
    assert sent["comment"] == "Good shadows; the glass is too dark."
    assert lms_.store.scores(aid)["failed"] == 0
    # a student may not ask for it; a 503 or a 429 stays pending (tried again later)
    r = client.post(f"/api/assignments/{aid}/lms/send-again", headers=bearer("x" * 43))
    assert r.status_code in (401, 403, 404), r.text
    for status in (429, 503, 401):
        from server.course.lms_poster import for_good
        from server.lti.services import ServiceError

        assert for_good(ServiceError(status, "x")) is None
    assert for_good(ServiceError(404, "x")) == 404 and for_good(ServiceError(0, "no answer")) is None


def test_lms_roster_sync_marks_students_who_left_inactive_adds_staff_and_a_returning_student_is_active(tool, lms):
    """NRPS: a student gone from the LMS course is kept, inactive (their submissions stay; they cannot submit);
    the LMS's instructors and TAs become the course's staff; a student back in the LMS course is active again."""
    url, app, client = tool
    p, aid = lms
    members = {"context_memberships_url": f"{p.url}/memberships/course-1?limit=2", "service_versions": ["2.0"]}
    p.do_launch(client, url, sub="teacher-1", roles=[LMS_INSTRUCTOR], custom={"assignment": aid},
                overrides={NRPS: members})  # fmt: skip
    ta_role = "http://purl.imsglobal.org/vocab/lis/v2/membership/Instructor#TeachingAssistant"
    ta = {"status": "Active", "name": "Tia Assistant", "email": "tia@example.edu", "user_id": "user-ta",
          "lis_person_sourcedid": "tia", "roles": [ta_role]}  # fmt: skip
    p.members["course-1"].append(ta)
    try:
        r = client.post("/api/courses/gfx/lms/sync", headers=ADMIN)
        assert r.status_code == 200, r.text
        roles = {s["id"]: s["role"] for s in client.get("/api/courses/gfx/staff", headers=ADMIN).json()["staff"]}
        assert roles.get("sis-0") == "instructor" and roles.get("tia") == "ta", roles
        roster = {s["id"]: s for s in client.get("/api/courses/gfx/roster", headers=ADMIN).json()["students"]}
        assert roster["sis-3"]["active"] is True
        gone = p.drop("course-1", "user-3")
        try:
            r = client.post("/api/courses/gfx/lms/sync", headers=ADMIN)
            assert r.status_code == 200 and r.json()["left"] >= 1, r.text
            roster = {s["id"]: s for s in client.get("/api/courses/gfx/roster", headers=ADMIN).json()["students"]}
            assert roster["sis-3"]["active"] is False
            assert roster["sis-3"]["left_at"] is not None  # kept, inactive
            assert roster["sis-1"]["active"] is True
            board = {
                s["id"]: s for s in client.get(f"/api/assignments/{aid}/dashboard", headers=ADMIN).json()["students"]
            }
            assert board["sis-3"]["active"] is False
            assert board["sis-1"]["active"] is True
            # they may read their assignment still, not submit
            m = app.state.course.store.member("gfx", "sis-3")
            token = app.state.course.token_of("gfx", "student", "sis-3", m["gen"])
            brief = client.get(f"/api/assignments/{aid}", headers=bearer(token)).json()
            assert brief["student"]["id"] == "sis-3" and brief["inactive"] is True, brief
            assert client.get(f"/api/assignments/{aid}/submissions", headers=bearer(token)).status_code == 200
            scene = (EXAMPLE / "class" / "alice.json").read_text()
            r = client.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=bearer(token))
            assert r.status_code == 403 and r.json()["errors"][0]["path"] == "student", r.text
        finally:
            p.members["course-1"].insert(3, gone)
        r = client.post("/api/courses/gfx/lms/sync", headers=ADMIN)
        assert r.status_code == 200 and r.json()["back"] >= 1, r.text
        roster = {s["id"]: s for s in client.get("/api/courses/gfx/roster", headers=ADMIN).json()["students"]}
        assert roster["sis-3"]["active"] is True
        assert roster["sis-3"]["left_at"] is None
        assert "inactive" not in client.get(f"/api/assignments/{aid}", headers=bearer(token)).json()
        trail = client.get("/api/courses/gfx/audit", params={"student": "sis-3"}, headers=ADMIN).json()["events"]
        moves = [
            (e["action"], e["who"], e["before"], e["after"])
            for e in trail
            if e["action"] in ("student.left", "student.back")
        ]
        assert moves[:2] == [
            ("student.back", "lms", {"active": False}, {"active": True}),
            ("student.left", "lms", {"active": True}, {"active": False}),
        ], trail  # the audit trail has both, newest first
    finally:
        p.members["course-1"].remove(ta)


def test_lms_a_student_who_launches_while_the_roster_is_read_stays_active(tool, lms):
    """The roster a sync reads may predate a launch made meanwhile (an instructor's launch syncs in the background
    while a student launches): a student who was not a member when the read began is not judged by it."""
    url, app, client = tool
    p, aid = lms
    lms_side = app.state.lms
    lms_side.store.set_memberships(p.registered_id, "course-1", f"{p.url}/memberships/course-1", None)
    read = lms_side.services.members

    def read_then_a_launch(platform, memberships_url, *args):
        roster = read(platform, memberships_url, *args)  # the LMS's answer, before the student is in it
        r = p.do_launch(client, url, sub="student-late", roles=[LEARNER], custom={"assignment": aid})
        assert r.status_code == 303, r.text
        return roster

    lms_side.services.members = read_then_a_launch
    try:
        synced = lms_side.sync("gfx")
    finally:
        del lms_side.services.members  # the instance's own again

    def late() -> list:
        return [m for m in app.state.course.store.members("gfx") if (m["lti_user"] or "").endswith(":student-late")]

    assert synced["members"] >= 1 and len(late()) == 1 and late()[0]["left_at"] is None, (synced, late())
    r = client.post("/api/courses/gfx/lms/sync", headers=ADMIN)  # the next read, with her not in it: inactive
    assert r.status_code == 200 and r.json()["left"] >= 1 and late()[0]["left_at"] is not None, (r.text, late())


def test_lms_deep_linking_honours_accept_types_and_accept_lineitem(tool, lms):
    """A deep-linking request whose accept_types has no ltiResourceLink gets a page that says why (no picker);
    one with accept_lineitem false gets its link without a lineItem."""
    url, app, client = tool
    p, aid = lms
    back = p.url + "/deep_link_return"
    r = p.do_launch(client, url, sub="teacher-1", roles=[LMS_INSTRUCTOR], message_type="LtiDeepLinkingRequest",
                    deep_linking={"deep_link_return_url": back, "accept_types": ["link", "file"]})  # fmt: skip
    assert r.status_code == 400 and "ltiResourceLink" in r.text and "link, file" in r.text, r.text
    assert 'name="pick"' not in r.text
    settings = {"deep_link_return_url": back, "accept_types": ["ltiResourceLink"], "accept_lineitem": False}
    r = p.do_launch(client, url, sub="teacher-1", roles=[LMS_INSTRUCTOR], message_type="LtiDeepLinkingRequest",
                    deep_linking=settings)  # fmt: skip
    assert r.status_code == 200 and "Pick an assignment" in r.text, r.text
    pick = re.search(r'name="pick" value="([^"]+)"', r.text)[1]
    r = client.post("/lti/pick", data={"pick": pick, "assignment": aid})
    jwt = re.search(r'name="JWT" value="([^"]+)"', r.text)[1]
    assert httpx.post(back, data={"JWT": jwt}).status_code == 200
    (item,) = p.deep_links[-1]["https://purl.imsglobal.org/spec/lti-dl/claim/content_items"]
    assert item["type"] == "ltiResourceLink"
    assert item["custom"] == {"assignment": aid}
    assert "lineItem" not in item
