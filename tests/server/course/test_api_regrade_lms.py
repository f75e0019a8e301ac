"""An accepted regrade request's points reach the LMS (server/course/regrade.py through the poster's re-post path,
server/course/lms_poster.py): a student launched from the test LMS (tests/support/lms.py) submits, the score goes
back; she asks about one test, the admin accepts it with other points, and the LMS gets the moved score. The app's
clock is a `Clock`; the launches' own times are the platform's real ones."""

from __future__ import annotations

from datetime import timedelta

import pytest

from tests.support.api import bearer, wait_for
from tests.support.lms import ADMIN, EXAMPLE, T0
from tests.support.lti_platform import LEARNER


def test_regrade_an_accepted_request_moves_the_score_at_the_lms(tool, lms):
    url, app, client = tool
    p, aid = lms
    r = p.do_launch(client, url, sub="student-7", roles=[LEARNER], custom={"assignment": aid})
    assert r.status_code == 303, r.text
    token = bearer(r.headers["location"].split("#token=")[1])
    scene = (EXAMPLE / "class" / "alice.json").read_text()
    r = client.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=token)
    assert r.status_code == 202, r.text
    sub = r.headers["location"]
    graded = wait_for(lambda: (s := client.get(sub, headers=token).json())["status"] == "graded" and s,
                      300, "the submission's grade", 0.5)  # fmt: skip
    wait_for(lambda: p.scores, 60, "the score at the LMS", 0.2)
    assert p.scores[0]["scoreGiven"] == pytest.approx(graded["score"])

    # the validity test (1 point, passed): accepted at 0.5, so the score moves by -0.5 at the LMS
    validity = next(t for t in graded["feedback"]["tests"] if t["test"] == "validity")
    r = client.post(f"{sub}/regrade-requests", json={"item": "validity", "reason": "please check"}, headers=token)
    assert r.status_code == 201, r.text
    app.state.clock.now = T0 + timedelta(hours=1)
    answer = {"status": "accepted", "reply": "half of it", "points": validity["score"] - 0.5}
    assert client.put(r.json()["url"], json=answer, headers=ADMIN).status_code == 200
    app.state.lms.poster.wake()
    wait_for(lambda: len(p.scores) == 2, 60, "the regraded score at the LMS", 0.2)
    assert p.scores[1]["scoreGiven"] == pytest.approx(graded["score"] - 0.5)
