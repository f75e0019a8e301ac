"""A pixel's two ray trees (GET /api/assignments/{aid}/submissions/{sid}/raytree, server/course/compare.py): a
student whose red ball is blue submits; at a pixel on that ball the trees differ in the eye ray's material, at a
pixel on the other ball they agree; both trees are traced by a real worker as the grader rendered the scenes.
The feedback policy's 403, an image's 409, an invalid submission's 409, x and y out of range (422), and the
404s of other students' work. Time is the app's injectable clock."""

from __future__ import annotations

import base64
import copy
import io
import json
import re
from datetime import UTC, datetime, timedelta

import pytest

from tests.support.api import INSTRUCTOR, bearer, course_client

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=1)
W, H = 32, 24

# A red ball in the middle (the centre pixel is on it), a green one to its right (pixel (25, 11)), a floor, one
# point light; max_depth 1: eye rays and shadow rays only.
REFERENCE = {
    "version": 1,
    "name": "two balls",
    "camera": {"lookfrom": [0, 0, 5], "lookat": [0, 0, 0], "vfov": 40},
    "film": {"width": W, "height": H},
    "sampler": {"type": "jittered", "spp": 1},
    "render": {"integrator": "whitted", "max_depth": 1},
    "background": [0.2, 0.3, 0.5],
    "ambient": 0.05,
    "materials": {"red": {"kd": [0.8, 0.1, 0.1]}, "green": {"kd": [0.1, 0.7, 0.1]}, "floor": {"kd": 0.5}},
    "lights": [{"type": "point", "position": [0, 4, 4], "intensity": 30}],
    "objects": [
        {"type": "plane", "name": "floor", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "floor"},
        {"type": "sphere", "name": "red ball", "center": [0, 0, 0], "radius": 0.8, "material": "red"},
        {"type": "sphere", "name": "green ball", "center": [1.5, 0, 0], "radius": 0.5, "material": "green"},
    ],
}
SPEC = {
    "version": 1,
    "name": "Two balls",
    "render": {"width": W, "height": H, "seed": 7, "spp": 1},
    "reference": {"scene": REFERENCE, "spp": 16, "pixels": {"points": 1}, "flip": {"points": 1}},
}
RED_BALL, GREEN_BALL = (16, 12), (25, 11)


def blue() -> dict:
    """The student's scene: the reference with the red ball blue."""
    scene = copy.deepcopy(REFERENCE)
    scene["materials"]["red"]["kd"] = [0.1, 0.1, 0.8]
    return scene


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    data = tmp_path_factory.mktemp("compare-data")
    with course_client(data, T0) as c:
        yield c


def publish(client, **policy) -> str:
    r = client.post("/api/assignments", json={"spec": SPEC, "deadline": DEADLINE.isoformat(), **policy})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def roster(client, aid: str, *ids: str) -> dict[str, str]:
    text = "id,name,email\n" + "".join(f"{i},Student {i},\n" for i in ids)
    r = client.post(f"/api/assignments/{aid}/roster", content=text, headers={"Content-Type": "text/csv"})
    assert r.status_code == 200, r.text
    return {s["id"]: s["token"] for s in r.json()["students"]}


def submit(client, aid: str, token: str, body: dict) -> str:
    r = client.post(f"/api/assignments/{aid}/submissions", json=body, headers=bearer(token))
    assert r.status_code == 202, r.text
    return r.json()["id"]


def finished(client, aid: str, sid: str) -> dict:
    from tests.support.api import wait_for

    def done():
        s = client.get(f"/api/assignments/{aid}/submissions/{sid}", headers=bearer(INSTRUCTOR)).json()
        return s["status"] in ("graded", "invalid", "failed") and s

    return wait_for(done, 240, f"submission {sid} graded", interval=0.1)


def trees(client, aid: str, sid: str, token: str, **query):
    return client.get(f"/api/assignments/{aid}/submissions/{sid}/raytree", params=query, headers=bearer(token))


@pytest.fixture(scope="module")
def graded(app):
    """One assignment (feedback shown now), two students: s1 submits the blue ball and a PNG, s2 an invalid scene."""
    aid = publish(app)
    tok = roster(app, aid, "s1", "s2")
    scene = submit(app, aid, tok["s1"], {"scene": blue()})
    from PIL import Image

    png = io.BytesIO()
    Image.new("RGB", (W, H), (90, 40, 40)).save(png, "PNG")
    image = submit(app, aid, tok["s1"], {"image": base64.b64encode(png.getvalue()).decode(), "format": "png"})
    bad = dict(blue(), objects=[{"type": "sphere", "center": [0, 0, 0], "radius": -1, "material": "red"}])
    invalid = submit(app, aid, tok["s2"], {"scene": bad})
    for sid in (scene, image, invalid):
        finished(app, aid, sid)
    return {"aid": aid, "tok": tok, "scene": scene, "image": image, "invalid": invalid}


def test_compare_a_pixel_on_the_recoloured_ball_differs_in_material(app, graded):
    aid, sid = graded["aid"], graded["scene"]
    view = app.get(f"/api/assignments/{aid}/submissions/{sid}", headers=bearer(graded["tok"]["s1"])).json()
    assert view["status"] == "graded"
    assert "error_map.png" in view["files"]
    r = trees(app, aid, sid, graded["tok"]["s1"], x=RED_BALL[0], y=RED_BALL[1])
    assert r.status_code == 200, r.text
    body = r.json()
    assert (body["x"], body["y"], body["sample"]) == (*RED_BALL, 0)
    for side in ("student", "reference"):
        tree = body[side]
        assert tree["pixel"] == list(RED_BALL)
        assert tree["nodes"][0]["kind"] == "eye"
        assert tree["nodes"][0]["hit"]["object_name"] == "red ball"
    # the same eye ray (same seed, sampler and settings): only the scenes differ
    assert body["student"]["nodes"][0]["direction"] == body["reference"]["nodes"][0]["direction"]
    d = body["difference"]
    assert d["what"] == "material"
    assert d["student"] == []
    assert d["reference"] == []
    assert d["nodes"] == {"student": 0, "reference": 0}
    assert d["message"].startswith("Where your eye ray hits red ball (material 'red'), as the reference's does, ")
    assert "(yours against the reference's): diffuse " in d["message"]
    assert "; ambient " in d["message"]
    assert d["message"].endswith("The material differs (kd: its colour, ka, which is kd unless set, or the scene's "
                                 "ambient), or a light's intensity.")  # fmt: skip
    s_diffuse = body["student"]["nodes"][0]["terms"]["diffuse"]
    r_diffuse = body["reference"]["nodes"][0]["terms"]["diffuse"]
    assert s_diffuse[2] > s_diffuse[0]
    assert r_diffuse[0] > r_diffuse[2]  # blue against red


def test_compare_a_pixel_where_they_agree_has_no_difference(app, graded):
    r = trees(app, graded["aid"], graded["scene"], INSTRUCTOR, x=GREEN_BALL[0], y=GREEN_BALL[1])
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["student"]["nodes"][0]["hit"]["object_name"] == "green ball"
    assert body["difference"] is None
    assert body["student"]["color"] == body["reference"]["color"]


def test_compare_the_reference_job_is_not_the_students(app, graded):
    """The reference's tree is traced as the instructor's job: the student's jobs hold only their own scene."""
    tok = graded["tok"]["s1"]
    assert trees(app, graded["aid"], graded["scene"], tok, x=3, y=20).status_code == 200
    jobs = app.get("/api/jobs", params={"kind": "raytree"}, headers=bearer(tok)).json()
    jobs = jobs["jobs"] if isinstance(jobs, dict) else jobs
    names = [j["name"] for j in jobs]
    assert any(n.startswith("ray tree (3, 20) of submission") for n in names), names
    assert not any(n.startswith("reference ray tree") for n in names), names


def test_compare_an_image_or_an_invalid_submission_has_no_scene_to_trace(app, graded):
    aid = graded["aid"]
    r = trees(app, aid, graded["image"], graded["tok"]["s1"], x=1, y=1)
    assert r.status_code == 409
    assert r.json()["errors"] == [
        {
            "path": "sid",
            "message": f"submission '{graded['image']}' is an image (PNG): there is no scene to trace; ray trees are "
            "compared for scene submissions",
        }
    ]
    r = trees(app, aid, graded["invalid"], graded["tok"]["s2"], x=1, y=1)
    assert r.status_code == 409
    assert r.json()["errors"][0]["message"].endswith("is invalid (its scene has errors): there is no render to compare")


def test_compare_x_and_y_out_of_the_graded_image(app, graded):
    aid, sid, tok = graded["aid"], graded["scene"], graded["tok"]["s1"]
    r = trees(app, aid, sid, tok, x=W, y=-1)
    assert r.status_code == 422
    assert r.json()["errors"] == [
        {"path": "x", "message": f"must be a column of the graded image in 0..{W - 1} (it is {W}x{H} pixels)"},
        {"path": "y", "message": f"must be a row of the graded image in 0..{H - 1} (it is {W}x{H} pixels)"},
    ]
    r = trees(app, aid, sid, tok, x=1, y=1, sample=5)  # 1 sample per pixel: only sample 0
    assert r.status_code == 422 and r.json()["errors"][0]["path"] == "sample", r.text
    r = trees(app, aid, sid, tok, y=1)
    assert r.status_code == 422 and "x" in json.dumps(r.json()["errors"])


def test_compare_other_students_work_is_a_404(app, graded):
    aid = graded["aid"]
    r = trees(app, aid, graded["scene"], graded["tok"]["s2"], x=1, y=1)  # s1's submission, asked by s2
    assert r.status_code == 404
    assert r.json()["errors"][0]["path"] == "sid"
    assert trees(app, aid, "0" * 32, graded["tok"]["s1"], x=1, y=1).status_code == 404
    assert trees(app, "f" * 32, graded["scene"], graded["tok"]["s1"], x=1, y=1).status_code == 404


def test_compare_follows_the_feedback_policy(app):
    """The pixels test's feedback after the deadline: before it the student's ask is a 403 saying when, the
    instructor's is answered; after it (the clock moved) the student's is too. Never: a 403 saying so."""
    aid = publish(app, feedback={"tests": {"pixels": "after_deadline"}})
    tok = roster(app, aid, "s1")["s1"]
    sid = submit(app, aid, tok, {"scene": blue()})
    r = trees(app, aid, sid, tok, x=RED_BALL[0], y=RED_BALL[1])
    assert r.status_code == 403
    assert r.json()["errors"] == [
        {
            "path": "sid",
            "message": "the ray trees at a pixel show the reference's scene: they are shown with the image tests' "
            "feedback (pixels), after your deadline, from 2026-12-02T12:00:00Z",
        }
    ]
    finished(app, aid, sid)
    assert trees(app, aid, sid, INSTRUCTOR, x=RED_BALL[0], y=RED_BALL[1]).json()["difference"]["what"] == "material"
    app.app.state.clock.now = DEADLINE + timedelta(seconds=1)
    try:
        r = trees(app, aid, sid, tok, x=RED_BALL[0], y=RED_BALL[1])
        assert r.status_code == 200, r.text
        assert r.json()["difference"]["what"] == "material"
    finally:
        app.app.state.clock.now = T0

    never = publish(app, feedback={"tests": {"flip": "never"}})
    tok = roster(app, never, "s1")["s1"]
    sid = submit(app, never, tok, {"scene": blue()})
    r = trees(app, never, sid, tok, x=1, y=1)
    assert r.status_code == 403
    assert r.json()["errors"][0]["message"].endswith("(flip) to students: they are not shown")
    finished(app, never, sid)  # graded before the server stops (the run's rows are kept either way)


def test_compare_a_submission_not_graded_yet_is_a_409(tmp_path):
    """A server without render workers renders nothing: a submission is never graded, and its ray trees wait."""
    with course_client(tmp_path / "data", T0, workers=0) as c:
        aid = publish(c)
        tok = roster(c, aid, "s1")["s1"]
        sid = submit(c, aid, tok, {"scene": blue()})
        r = trees(c, aid, sid, tok, x=1, y=1)
        assert r.status_code == 409
        (error,) = r.json()["errors"]
        assert error["path"] == "sid"  # queued, or prepared (its checks made) and waiting for its render
        assert re.fullmatch(f"submission '{sid}' is (queued|being graded): its ray trees can be compared once it is "
                            "graded", error["message"]), error  # fmt: skip
