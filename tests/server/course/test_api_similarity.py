"""Similarity reports on the service (issue #41, item 6; server/course/similarity.py, server/api/routes/similarity.py):
`python -m server` on loopback, a course with an instructor and a TA, an assignment whose policy hands out a
starter scene, and a class of eight: seven who each made their own scene from the starter, one of whose scenes is
copied by the eighth with its objects and lights reordered, its materials renamed and every fractional number
nudged by +0.001 (bench/similarity.py's `disguised`). The staff ask for a report (202, computed in a grading
process) and read it: the copied pair is flagged first, with the facts side by side, and no pair of the honest
students is; a student gets 403, another course's instructor the 404 of an unknown id. No render worker: the
report reads the submissions' files, whatever their grades."""

from __future__ import annotations

import json
import random

import pytest

from bench.similarity import disguised, honest, starter
from tests.support.api import INSTRUCTOR, Server, bearer, wait_for
from tests.support.scene import ROOT

EXAMPLE = ROOT / "scenes" / "grading"
DEADLINE = "2100-01-01T12:00:00Z"
ADMIN = bearer(INSTRUCTOR)


def spec() -> dict:
    a = json.loads((EXAMPLE / "assignment.json").read_text())
    a["reference"]["scene"] = json.loads((EXAMPLE / "reference.json").read_text())
    return a


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("similarity") / "data", workers=0,
                env={"TRACER_INSTRUCTOR_TOKEN": INSTRUCTOR}) as s:  # fmt: skip
        yield s


@pytest.fixture(scope="module")
def course(server):
    """Course cs1 with an instructor and a TA, cs2 with its own instructor; an assignment of cs1 with the
    starter; its roster of nine, each of whom has submitted once (h0..h6 their own, cp a copy of h3's)."""
    c = server.client
    people = {}
    for cid in ("cs1", "cs2"):
        assert c.post("/api/courses", json={"id": cid, "name": cid}, headers=ADMIN).status_code == 201
    for cid, person, role in (("cs1", "prof", "instructor"), ("cs1", "tee", "ta"), ("cs2", "other", "instructor")):
        r = c.post(f"/api/courses/{cid}/staff", json={"id": person, "name": person, "role": role}, headers=ADMIN)
        assert r.status_code == 201, r.text
        people[person] = bearer(r.json()["token"])
    r = c.post("/api/assignments", json={"spec": spec(), "deadline": DEADLINE, "starter": starter()},
               headers=people["prof"])  # fmt: skip
    assert r.status_code == 201, r.text
    aid = r.json()["id"]
    names = [f"h{i}" for i in range(7)] + ["cp"]
    roster = "id,name,email\n" + "".join(f"{n},{n.upper()},\n" for n in names)
    r = c.post(f"/api/assignments/{aid}/roster", content=roster, headers={**people["prof"], "Content-Type": "text/csv"})
    assert r.status_code == 200, r.text
    tokens = {s["id"]: bearer(s["token"]) for s in r.json()["students"]}
    rng = random.Random(11)
    scenes = {f"h{i}": honest(rng) for i in range(7)}
    scenes["cp"] = disguised(rng, scenes["h3"])
    for who, scene in scenes.items():
        r = c.post(f"/api/assignments/{aid}/submissions", json={"scene": scene}, headers=tokens[who])
        assert r.status_code == 202, r.text
    return {"aid": aid, "people": people, "tokens": tokens}


def report(server: Server, aid: str, headers: dict) -> dict:
    return wait_for(
        lambda: (
            (r := server.client.get(f"/api/assignments/{aid}/similarity", headers=headers).json())["status"]
            in ("done", "failed")
            and r
        ),
        120,
        "the similarity report",
        interval=0.1,
    )


def test_similarity_the_copied_scene_is_flagged_first_and_no_honest_pair(server, course):
    aid, prof = course["aid"], course["people"]["prof"]
    url = f"/api/assignments/{aid}/similarity"
    before = server.client.get(url, headers=prof).json()
    assert before["status"] == "none"
    assert before["pairs"] == []
    assert "for a person to look at" in before["note"]
    r = server.client.post(url, headers=prof)
    assert r.status_code == 202, r.text
    assert r.json()["status"] == "computing"
    assert r.json()["students"] == 8
    out = report(server, aid, prof)
    assert out["status"] == "done", out
    first = out["pairs"][0]
    assert {first["a"], first["b"]} == {"h3", "cp"}, out["pairs"]
    assert len(out["pairs"]) == 1, out["pairs"]  # no pair of the honest students
    assert all(p["score"] > out["groups"]["scene"]["threshold"] for p in out["closest"])
    assert first["score"] < first["typical"] / 2
    assert first["typical"] == out["groups"]["scene"]["typical"]
    shared = [f for f in first["facts"] if f["shared"]]
    assert len(shared) >= 5, first["facts"]
    assert not any(f["path"].startswith("plane@") for f in first["facts"])  # the starter's floor: no evidence
    assert {"path", "a", "b", "shared"} <= set(first["facts"][0])
    assert out["since"] == 0
    assert out["computed_at"]
    assert out["skipped"] == []
    assert "median" in out["how"]
    assert "not a finding of misconduct" in out["note"]


def test_similarity_a_ta_may_ask_a_student_may_not(server, course):
    aid, url = course["aid"], f"/api/assignments/{course['aid']}/similarity"
    r = server.client.post(url, headers=course["people"]["tee"])
    assert r.status_code == 202, r.text
    assert report(server, aid, course["people"]["tee"])["status"] == "done"
    for method in ("get", "post"):
        r = getattr(server.client, method)(url, headers=course["tokens"]["h1"])
        assert r.status_code == 403, r.text
        assert r.json()["errors"][0]["path"] == "Authorization"
        assert "staff" in r.json()["errors"][0]["message"]
    assert server.client.get(url, headers=course["people"]["other"]).status_code in (401, 404)
    r = server.client.get("/api/assignments/" + "0" * 32 + "/similarity", headers=ADMIN)
    assert r.status_code == 404
    assert r.json()["errors"][0]["path"] == "id"


def test_similarity_a_submission_after_the_report_is_counted_as_since(server, course):
    aid, prof = course["aid"], course["people"]["prof"]
    r = server.client.post(f"/api/assignments/{aid}/submissions", json={"scene": honest(random.Random(99))},
                           headers=course["tokens"]["h5"])  # fmt: skip
    assert r.status_code == 202, r.text
    out = server.client.get(f"/api/assignments/{aid}/similarity", headers=prof).json()
    assert out["status"] == "done"
    assert out["since"] == 1
