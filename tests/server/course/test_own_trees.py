"""A student's own tracer's tree log on the service (POST /api/assignments/{aid}/submissions/{sid}/trees and
`trees` in the check; server/course/owntrees.py): the probes in an image's feedback, a log that matches the
reference's trees, one whose eye ray is off by half a pixel (`eye_ray`), a log with errors (422, every error at its
path), a log past the limit (413), the policy's 403 and the probes hidden with the error map, a scene's 409,
another student's 404, and the check. The reference's trees are traced by a real worker. Time is the app's
injectable clock."""

from __future__ import annotations

import base64
import copy
import io
import json
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from tests.support.api import INSTRUCTOR, bearer, course_client, wait_for
from tests.support.own_trees import REFERENCE, H, W

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
DEADLINE = T0 + timedelta(days=1)

SPEC = {
    "version": 1,
    "name": "Own tracer",
    "render": {"width": W, "height": H, "seed": 7, "spp": 1},
    "reference": {"scene": REFERENCE, "spp": 64, "flip": {"points": 1}, "probes": [{"x": 3, "y": 20, "why": "floor"}]},
}
PIXELS = [(12, 12), (24, 14), (3, 20), (1, 1)]  # the mirror ball, the red ball, the floor, the background


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with course_client(tmp_path_factory.mktemp("own-trees"), T0) as c:
        yield c


@pytest.fixture(scope="module")
def ex():
    from tracer.grading.explain import Explainer

    return Explainer(REFERENCE)


def reference_log(ex, pixels) -> dict:
    """A log as a correct tracer writes it: the reference's own trees, with only the contract's fields."""
    from tracer.grading.treelog import as_logged

    return {"trees": [as_logged(ex.reference_tree(x, y)) for x, y in pixels]}


def png_of(image: np.ndarray) -> str:
    from PIL import Image

    from tracer.rendering.film import to_srgb8

    buf = io.BytesIO()
    Image.fromarray(to_srgb8(image)).save(buf, "PNG")
    return base64.b64encode(buf.getvalue()).decode()


def rendered() -> np.ndarray:
    """A student's right image: the reference scene, antialiased as the reference mean is."""
    from tracer.kernels.compile import compile_scene
    from tracer.rendering.progressive import render
    from tracer.scene import load_scene

    scene, _ = load_scene(dict(REFERENCE, sampler={"type": "jittered", "spp": 64}))
    return render(compile_scene(scene)).image


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
    sid = r.json()["id"]

    def done():
        s = client.get(f"/api/assignments/{aid}/submissions/{sid}", headers=bearer(INSTRUCTOR)).json()
        return s["status"] in ("graded", "invalid", "failed") and s

    wait_for(done, 240, f"submission {sid} graded", interval=0.1)
    return sid


@pytest.fixture(scope="module")
def graded(app):
    """s1 hands in a right image and a wrong one (the red ball dark); s2 a scene."""
    aid = publish(app)
    tok = roster(app, aid, "s1", "s2")
    image = rendered()
    right = submit(app, aid, tok["s1"], {"image": png_of(image), "format": "png"})
    dark = image.copy()
    dark[10:20, 20:30] *= 0.2
    wrong = submit(app, aid, tok["s1"], {"image": png_of(dark), "format": "png"})
    scene = submit(app, aid, tok["s2"], {"scene": REFERENCE})
    return {"aid": aid, "tok": tok, "right": right, "wrong": wrong, "scene": scene}


def post_trees(app, graded, sid: str, body, token: str | None = None):
    url = f"/api/assignments/{graded['aid']}/submissions/{sid}/trees"
    content = body if isinstance(body, bytes) else json.dumps(body).encode()
    headers = {**bearer(token or graded["tok"]["s1"]), "Content-Type": "application/json"}
    return app.post(url, content=content, headers=headers)


def test_own_trees_the_feedback_lists_probes_where_the_image_differs(app, graded):
    view = app.get(f"/api/assignments/{graded['aid']}/submissions/{graded['wrong']}",
                   headers=bearer(graded["tok"]["s1"])).json()  # fmt: skip
    probes = view["feedback"]["probes"]
    assert probes[0] == {"x": 3, "y": 20, "why": "floor"}, probes  # the spec's own, first
    found = probes[1:]
    assert found, view["feedback"]
    # in the darkened square, or a pixel or two beside it (FLIP's filters spread an edge's error)
    assert all(18 <= p["x"] < 32 and 8 <= p["y"] < 22 for p in found), found
    assert 20 <= found[0]["x"] < 30 and 10 <= found[0]["y"] < 20, found[0]
    assert all("error map" in p["why"] for p in found)
    right = app.get(f"/api/assignments/{graded['aid']}/submissions/{graded['right']}",
                    headers=bearer(graded["tok"]["s1"])).json()  # fmt: skip
    assert right["feedback"]["probes"] == [{"x": 3, "y": 20, "why": "floor"}]  # no region: nothing differs


def test_own_trees_a_right_log_matches_and_a_half_pixel_eye_ray_is_named(app, graded, ex):
    log = reference_log(ex, PIXELS)
    r = post_trees(app, graded, graded["right"], log)
    assert r.status_code == 200, r.text
    answer = r.json()
    assert [t["pixel"] for t in answer["trees"]] == [list(p) for p in PIXELS]
    assert [t["matches"] for t in answer["trees"]] == [True] * len(PIXELS), answer["trees"][0]["differences"]
    # the reference's trees are the kernels' own (the same as the library's)
    assert answer["trees"][0]["reference"]["color"] == ex.reference_tree(*PIXELS[0])["color"]
    # the scene they were traced in, for the page's overlay and 3D views (its camera and objects)
    assert answer["scene"]["camera"]["lookfrom"] == REFERENCE["camera"]["lookfrom"]
    assert [o["name"] for o in answer["scene"]["objects"]] == [o["name"] for o in REFERENCE["objects"]]
    bad = copy.deepcopy(log)
    x, y = PIXELS[1]
    forward, right, up, h, aspect = ex.camera_frame()
    corner = forward + (2 * x / W - 1) * h * aspect * right + (1 - 2 * y / H) * h * up  # the pixel's corner
    bad["trees"][1]["nodes"][0]["direction"] = [float(c) for c in corner]
    r = post_trees(app, graded, graded["right"], bad)
    assert r.status_code == 200, r.text
    t = r.json()["trees"][1]
    assert t["matches"] is False
    first = t["differences"][0]
    assert first["what"] == "eye_ray"
    assert first["student"] == 0
    assert first["reference"] == 0
    assert "corner" in first["message"] and "(x + 0.5, y + 0.5)" in first["message"], first["message"]
    # the latest comparison is kept: the student and the staff read it again, and the dashboard counts it
    url = f"/api/assignments/{graded['aid']}/submissions/{graded['right']}/trees"
    for token in (graded["tok"]["s1"], INSTRUCTOR):  # the instructor's view on /course reads it
        again = app.get(url, headers=bearer(token))
        assert again.status_code == 200 and again.json() == r.json(), again.text
    assert app.get(url, headers=bearer(graded["tok"]["s2"])).status_code == 404
    board = app.get(f"/api/assignments/{graded['aid']}/dashboard", headers=bearer(INSTRUCTOR)).json()
    assert board["tree_whats"] == {"eye_ray": 1}, board["tree_whats"]


def test_own_trees_a_bad_log_is_a_422_with_every_error_at_its_path(app, graded, ex):
    log = reference_log(ex, PIXELS[:1])
    log["trees"][0]["nodes"][0]["kind"] = "camera"
    log["trees"][0]["nodes"][1]["direction"] = [0, 0]
    log["trees"].append({"pixel": [W, 0], "nodes": [{"id": 0, "parent": None, "kind": "eye", "origin": [0, 0, 0],
                                                     "direction": [0, 0, -1], "t": None}]})  # fmt: skip
    r = post_trees(app, graded, graded["right"], log)
    assert r.status_code == 422, r.text
    paths = {e["path"]: e["message"] for e in r.json()["errors"]}
    assert "trees[0].nodes[0].kind" in paths
    assert "eye" in paths["trees[0].nodes[0].kind"]
    assert "trees[0].nodes[1].direction[2]" in paths
    assert "trees[1].pixel" in paths
    assert f"x in 0..{W - 1}" in paths["trees[1].pixel"]
    r = post_trees(app, graded, graded["right"], b"{not json")
    assert r.status_code == 422 and "JSON" in r.json()["errors"][0]["message"], r.text
    r = post_trees(app, graded, graded["right"], {"trees": [{"pixel": [0, 0], "nodes": []}] * 65})
    assert r.status_code == 422 and r.json()["errors"][0]["path"] == "trees", r.text
    big = b'{"trees": [], "pad": "' + b"x" * 4_000_000 + b'"}'
    r = post_trees(app, graded, graded["right"], big)
    assert r.status_code == 413 and "TRACER_MAX_TREE_LOG_BYTES" in r.json()["errors"][0]["message"], r.text


def test_own_trees_who_may_and_when(app, graded, ex, tmp_path):
    log = reference_log(ex, PIXELS[:1])
    r = post_trees(app, graded, graded["right"], log, graded["tok"]["s2"])  # another student's
    assert r.status_code == 404, r.text
    r = post_trees(app, graded, graded["right"], log, INSTRUCTOR)
    assert r.status_code == 200 and r.json()["trees"][0]["matches"], r.text
    r = post_trees(app, graded, graded["scene"], log, graded["tok"]["s2"])
    assert r.status_code == 409 and "scene" in r.json()["errors"][0]["message"], r.text
    # an assignment that shows the image tests only after the deadline: no trees and no probes yet
    aid = publish(app, feedback={"default": "now", "tests": {"flip": "after_deadline"}})
    tok = roster(app, aid, "s3")
    sid = submit(app, aid, tok["s3"], {"image": png_of(rendered()), "format": "png"})
    url = f"/api/assignments/{aid}/submissions/{sid}/trees"
    headers = {**bearer(tok["s3"]), "Content-Type": "application/json"}
    r = app.post(url, content=json.dumps(log).encode(), headers=headers)
    assert r.status_code == 403 and "after your deadline" in r.json()["errors"][0]["message"], r.text
    feedback = app.get(f"/api/assignments/{aid}/submissions/{sid}", headers=bearer(tok["s3"])).json()["feedback"]
    assert "probes" not in feedback
    assert "after your deadline" in feedback["probes_hidden"], feedback
    r = app.post(f"/api/assignments/{aid}/check", json={"image": png_of(rendered()), "format": "png"},
                 headers=bearer(tok["s3"]))  # fmt: skip
    assert "probes" not in r.json() and "after your deadline" in r.json()["probes_hidden"], r.json()


def test_own_trees_the_check_compares_a_log_and_keeps_nothing(app, graded, ex):
    log = reference_log(ex, PIXELS[:2])
    log["trees"][1]["nodes"][0]["origin"] = [0, 0.5, 6]
    body = {"image": png_of(rendered()), "format": "png", "trees": log}
    r = app.post(f"/api/assignments/{graded['aid']}/check", json=body, headers=bearer(graded["tok"]["s1"]))
    assert r.status_code == 200, r.text
    assert r.json()["probes"] == [{"x": 3, "y": 20, "why": "floor"}], r.json()  # the spec's own: nothing differs
    trees = r.json()["trees"]
    assert trees[0]["matches"] is True
    assert trees[1]["differences"][0]["what"] == "eye_ray"
    assert "lookfrom" in trees[1]["differences"][0]["message"]
    dark = rendered()
    dark[10:20, 20:30] *= 0.2
    r = app.post(f"/api/assignments/{graded['aid']}/check", json={"image": png_of(dark), "format": "png"},
                 headers=bearer(graded["tok"]["s1"]))  # fmt: skip
    found = r.json()["probes"][1:]
    assert found and 20 <= found[0]["x"] < 30 and 10 <= found[0]["y"] < 20, r.json()
    r = app.post(f"/api/assignments/{graded['aid']}/check", json={"scene": REFERENCE, "trees": log},
                 headers=bearer(graded["tok"]["s1"]))  # fmt: skip
    assert r.status_code == 422 and r.json()["errors"][0]["path"] == "trees", r.text
