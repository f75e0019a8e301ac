"""A feedback policy that hides one image test (issue #42, Major 1): what a student sees while it is hidden, and
the publish form's preview of it (POST /api/assignments/preview-feedback, server/course/policy.py).

`python -m server` on loopback with one render worker and an instructor token; the docs' own example policy
(`pixels` shown after the deadline) on a tiny version of the example assignment (32 x 24 pixels: graded in
seconds). A student's scene with its light dimmed misses the reference in FLIP, SSIM and PSNR, whose outputs say
where to look: while the error map and the rejected pixels are hidden, no shown text may point at them, and the
feedback says what is hidden and when it appears. An extension to an hour ago puts a second student after their
deadline: everything shown, the pictures named again. The server's clock is the real one: the deadline is a day
away, never waited for."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import httpx
import pytest

from tests.support.api import INSTRUCTOR, Server, bearer, wait_for
from tests.support.feedback_policy import POLICY, dimmed, spec
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
TEACHER = bearer(INSTRUCTOR)
PICTURE_WORDS = ("error map", "rejected pixels", "picture")  # what a text pointing at a hidden picture says


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    env = {"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}
    with Server(tmp_path_factory.mktemp("feedback-policy-data"), workers=1, env=env) as s:
        yield s


def body(deadline: datetime) -> dict:
    return {"spec": spec(), "deadline": deadline.isoformat(), **POLICY}


def mentions_pictures(text: str) -> list[str]:
    return [w for w in PICTURE_WORDS if w in text.lower()]


def test_a_hidden_image_test_leaves_no_text_pointing_at_a_missing_picture(server):
    deadline = (datetime.now(UTC) + timedelta(days=1)).replace(microsecond=0)
    r = httpx.post(f"{server.url}/api/assignments", json=body(deadline), headers=TEACHER, timeout=60)
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    text = "id,name,email\nnow,Student Now,n@x.edu\nafter,Student After,a@x.edu\n"
    r = httpx.post(f"{server.url}/api/assignments/{aid}/roster", content=text,
                   headers={**TEACHER, "Content-Type": "text/csv"}, timeout=30)  # fmt: skip
    assert r.status_code == 200, r.text
    tok = {s["id"]: s["token"] for s in r.json()["students"]}
    subs = {}
    for who in tok:
        r = httpx.post(f"{server.url}/api/assignments/{aid}/submissions", json={"scene": dimmed()},
                       headers=bearer(tok[who]), timeout=30)  # fmt: skip
        assert r.status_code == 202, r.text
        subs[who] = r.json()["id"]
    # the second student's deadline moved to an hour ago: they are past it (the feedback after the deadline)
    hour_ago = (datetime.now(UTC) - timedelta(hours=1)).replace(microsecond=0)
    r = httpx.post(f"{server.url}/api/assignments/{aid}/extensions", json={"student": "after", "deadline":
                   hour_ago.isoformat()}, headers=TEACHER, timeout=30)  # fmt: skip
    assert r.status_code == 200, r.text

    def graded(who: str):
        s = httpx.get(f"{server.url}/api/assignments/{aid}/submissions/{subs[who]}", headers=bearer(tok[who]),
                      timeout=30).json()  # fmt: skip
        return s["status"] in ("graded", "invalid", "failed") and s

    now = wait_for(lambda: graded("now"), 240, "the first submission graded", interval=0.2)
    after = wait_for(lambda: graded("after"), 240, "the second submission graded", interval=0.2)
    assert now["status"] == after["status"] == "graded", now
    tests = {t["test"]: t for t in now["feedback"]["tests"]}
    missed = [k for k in ("flip", "ssim", "psnr") if tests[k].get("status") == "failed"]
    assert missed, f"the dimmed scene passed every image test: {tests}"

    # until the deadline: pixels hidden, and with it the error map and the rejected pixels
    assert tests["pixels"]["hidden"] == "shown after the deadline"
    assert "output" not in tests["pixels"]
    assert sorted(now["files"]) == ["render.png"]
    assert now["feedback"]["pictures"] == []
    for k in missed:
        out = tests[k]["output"]
        where = [line for line in out.split("\n") if line.startswith("Where to look: ")]
        assert where, out  # it still says what to compare in the scene
        assert mentions_pictures(where[0]) == [], f"{k}'s output points at a hidden picture: {where[0]}"
        assert f"shown after the deadline, from {deadline:%Y-%m-%d %H:%M} UTC." in out, out  # and when they come
    cut = deadline.isoformat().replace("+00:00", "Z")
    [notice] = now["feedback"]["withheld"]
    assert notice["when"] == "after_deadline"
    assert notice["at"] == cut
    assert notice["tests"] == ["pixels"]
    assert notice["pictures"] == ["error_map.png", "rejected.png"]
    assert "the error map" in notice["parts"]
    assert "the rejected pixels" in notice["parts"]
    assert notice["message"].endswith(f"shown after the deadline, from {cut}."), notice["message"]

    # after their deadline: everything shown, and the pictures named again where they are
    atests = {t["test"]: t for t in after["feedback"]["tests"]}
    assert atests["pixels"]["status"] in ("passed", "failed")
    assert after["feedback"]["withheld"] == []
    assert sorted(after["files"]) == ["error_map.png", "rejected.png", "render.png"]
    assert any("the FLIP error map" in atests[k]["output"] for k in missed)


def test_the_preview_shows_what_a_student_sees_now_and_after_the_deadline(server):
    deadline = datetime(2026, 12, 9, 17, 0, tzinfo=UTC)
    listed = lambda: httpx.get(f"{server.url}/api/assignments", headers=TEACHER, timeout=30).json()  # noqa: E731
    published = listed()
    r = httpx.post(f"{server.url}/api/assignments/preview-feedback", json=body(deadline), headers=TEACHER, timeout=60)
    assert r.status_code == 200, r.text
    p = r.json()
    assert p["deadline"] == p["cut_off"] == "2026-12-09T17:00:00Z"
    before, after = p["moments"]
    assert (before["moment"], after["moment"]) == ("now", "after_deadline")
    b = {t["test"]: t for t in before["feedback"]["tests"]}
    # the requirements are the reference's own results (it meets them); the image tests an example miss
    assert b["validity"]["status"] == "passed"
    assert b["a glass object"]["status"] == "passed"
    assert b["pixels"]["hidden"] == "shown after the deadline"
    assert b["pixels"]["shown_at"] == "2026-12-09T17:00:00Z"
    for k in ("flip", "ssim", "psnr"):
        assert b[k]["status"] == "failed"
        where = next(line for line in b[k]["output"].split("\n") if line.startswith("Where to look: "))
        assert mentions_pictures(where) == [], where
    assert before["feedback"]["pictures"] == []
    assert "metrics" not in before["feedback"]
    assert before["feedback"]["withheld"][0]["at"] == "2026-12-09T17:00:00Z"
    assert before["score_shown"] is True
    assert before["score"] is not None  # the policy shows the score now
    a = {t["test"]: t for t in after["feedback"]["tests"]}
    assert a["pixels"]["status"] == "failed"
    assert after["feedback"]["withheld"] == []
    assert after["feedback"]["pictures"] == ["error_map.png", "rejected.png"]
    assert "metrics" in after["feedback"]
    assert "the FLIP error map" in a["flip"]["output"]
    assert listed() == published  # nothing published


def test_the_preview_checks_the_body_as_publishing_does(server):
    bad = body(datetime(2026, 12, 9, 17, 0, tzinfo=UTC))
    bad["feedback"] = {"tests": {"colour": "now"}}
    r = httpx.post(f"{server.url}/api/assignments/preview-feedback", json=bad, headers=TEACHER, timeout=60)
    assert r.status_code == 422 and r.json()["errors"][0]["path"] == "feedback.tests.colour", r.text
    good = body(datetime(2026, 12, 9, 17, 0, tzinfo=UTC))
    r = httpx.post(f"{server.url}/api/assignments/preview-feedback", json=good, headers=bearer("x" * 40), timeout=60)
    assert r.status_code in (401, 403), r.text


def test_an_image_test_never_shown_says_so_and_the_instructor_sees_everything():
    """policy.feedback_view alone (the rule both the service and the preview use): `flip` never shown keeps the
    pictures from students for good, and the other image tests' outputs say so; the instructor sees all."""
    from server.course.policy import Feedback, Moment, feedback_view
    from tracer.grading.imagetests import where_without_pictures

    where = "Where to look: the FLIP error map (bright where the pictures differ most) and the rejected pixels (red); "
    scene_where = "compare those parts of your scene with the reference: an object's place or size, a material's "
    output = f"Differs.\nNumbers.\n{where}{scene_where}colour or its kr, kt and ks, a light's position or intensity."
    report = {"tests": [{"name": "FLIP against the reference", "score": 0, "max_score": 2, "status": "failed",
                         "output": "hidden words"},
                        {"name": "SSIM against the reference", "score": 0, "max_score": 1, "status": "failed",
                         "output": output}], "metrics": {"flip": 0.3}}  # fmt: skip
    feedback = Feedback.model_validate({"tests": {"flip": "never"}})
    student = feedback_view(report, ["flip", "ssim"], ["flip", "ssim"], feedback, Moment(10.0, 5.0), "scene")
    flip, ssim = student["tests"]
    assert flip["hidden"] == "shown never"
    assert "shown_at" not in flip
    assert "error map" not in ssim["output"].split("\n")[2]
    assert ssim["output"].split("\n")[2].startswith("Where")
    assert ssim["output"].endswith("The error map and the rejected pixels are never shown to students for this "
                                   "assignment (your instructor sees them).")  # fmt: skip
    [group] = student["withheld"]
    assert group["when"] == "never"
    assert group["at"] is None
    assert group["tests"] == ["flip"]
    assert student["pictures"] == []
    assert "metrics" not in student
    teacher = feedback_view(report, ["flip", "ssim"], ["flip", "ssim"], feedback, Moment(0.0, 5.0, True), "scene")
    assert teacher["withheld"] == []
    assert teacher["tests"][1]["output"] == output
    assert teacher["metrics"]
    assert where_without_pictures("no such line", "note") == "no such line"
