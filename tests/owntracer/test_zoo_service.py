"""The bug zoo through the service: the zoo's student hands in their tracer's picture of the zoo scene (an
assignment whose reference it is), reads the probes, and POSTs the tree logs of their tracer with one bug at a
time to /api/assignments/{aid}/submissions/{sid}/trees; the service names each bug first at 3 of its pixels or
more, and the correct tracer's trees match at every probe. A real worker traces the reference's trees."""

from __future__ import annotations

import base64
import json
from datetime import UTC, datetime, timedelta

import pytest

from tests.owntracer.zoo_tracer import BUGS, bug_pixels, png_bytes, zoo_render, zoo_scene
from tests.support.api import INSTRUCTOR, bearer, course_client, wait_for

T0 = datetime(2026, 12, 1, 12, 0, tzinfo=UTC)
SAMPLES = 6  # pixels sent per bug
BY_SERVICE = ("shadow_acne", "no_attenuation", "no_tir", "depth_off_by_one", "half_pixel", "no_srgb")


@pytest.fixture(scope="module")
def zoo(tmp_path_factory):
    """The assignment, its student, and two graded submissions: the correct tracer's picture and the one
    without the sRGB curve (the only bug whose tree is right and whose picture is not)."""
    with course_client(tmp_path_factory.mktemp("zoo-service"), T0) as app:
        spec = {"version": 1, "name": "The bug zoo",
                "reference": {"scene": zoo_scene(), "spp": 16, "flip": {"points": 1}}}  # fmt: skip
        r = app.post("/api/assignments", json={"spec": spec, "deadline": (T0 + timedelta(days=1)).isoformat()})
        assert r.status_code == 201, r.text
        aid = r.json()["id"]
        r = app.post(f"/api/assignments/{aid}/roster", content="id,name,email\nz1,Zoe,\n",
                     headers={"Content-Type": "text/csv"})  # fmt: skip
        token = r.json()["students"][0]["token"]
        subs = {}
        for bug in (None, "no_srgb"):
            image, _, _ = zoo_render(bug)
            picture = png_bytes(image, zoo_scene()["film"].get("exposure", 0.0), () if bug is None else (bug,))
            body = {"image": base64.b64encode(picture).decode(), "format": "png"}
            r = app.post(f"/api/assignments/{aid}/submissions", json=body, headers=bearer(token))
            assert r.status_code == 202, r.text
            sid = r.json()["id"]

            def graded(sid=sid):
                s = app.get(f"/api/assignments/{aid}/submissions/{sid}", headers=bearer(INSTRUCTOR)).json()
                return s["status"] in ("graded", "invalid", "failed") and s

            assert wait_for(graded, 240, f"submission {sid} graded", interval=0.1)["status"] == "graded"
            subs[bug] = sid
        yield app, aid, token, subs


def spread(pixels: list, n: int = SAMPLES) -> list:
    if len(pixels) <= n:
        return list(pixels)
    return [pixels[(2 * i + 1) * len(pixels) // (2 * n)] for i in range(n)]


def post(app, aid: str, sid: str, token: str, trees: list[dict]) -> list[dict]:
    r = app.post(f"/api/assignments/{aid}/submissions/{sid}/trees", content=json.dumps({"trees": trees}).encode(),
                 headers={**bearer(token), "Content-Type": "application/json"})  # fmt: skip
    assert r.status_code == 200, r.text
    return r.json()["trees"]


@pytest.mark.parametrize("bug", BY_SERVICE)
def test_zoo_service_names_the_bug(zoo, bug):
    app, aid, token, subs = zoo
    _, trees, _ = zoo_render(bug)
    pixels = spread(bug_pixels(bug))
    answers = post(app, aid, subs["no_srgb" if bug == "no_srgb" else None], token, [trees[p] for p in pixels])
    firsts = {tuple(a["pixel"]): a["differences"][0]["what"] if a["differences"] else None for a in answers}
    named = [p for p, what in firsts.items() if what == BUGS[bug]]
    assert len(named) >= 3, f"{bug}: expected '{BUGS[bug]}' first at 3 pixels or more: {firsts}"
    for a in answers:
        for d in a["differences"]:
            assert d["message"] and (d["student"] is not None or d["reference"] is not None), d


def test_zoo_service_the_correct_tracer_matches_at_every_probe(zoo):
    app, aid, token, subs = zoo
    view = app.get(f"/api/assignments/{aid}/submissions/{subs[None]}", headers=bearer(token)).json()
    probes = [(p["x"], p["y"]) for p in view["feedback"]["probes"]]
    _, trees, _ = zoo_render(None)
    pixels = probes + [p for p in spread(sorted(trees), 12) if p not in probes]  # the probes and more
    answers = post(app, aid, subs[None], token, [trees[p] for p in pixels])
    assert [a["pixel"] for a in answers] == [list(p) for p in pixels]
    wrong = {tuple(a["pixel"]): a["differences"][:1] for a in answers if not a["matches"]}
    assert wrong == {}, json.dumps(list(wrong.values())[:2])
