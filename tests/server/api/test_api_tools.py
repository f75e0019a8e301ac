"""The tool and example routes (server/api/routes/tools.py, scenes.py) and the API's own docs, through the
TestClient of an app without workers (the jobs: test_api_jobs.py and the other test_api_*.py)."""

import pytest

from tests.support.api import INSTRUCTOR, bearer
from tests.support.scene import scene_dict, small


@pytest.fixture
def client(client_without_workers):
    return client_without_workers


def test_api_tools_health_schema_and_scenes(client):
    health = client.get("/api/health").json()
    assert health["status"] == "ok"
    assert health["workers"] == []
    assert health["jobs"]["queued"] == 0
    schema = client.get("/api/schema").json()
    assert "properties" in schema
    assert "camera" in schema["properties"]
    names = [s["name"] for s in client.get("/api/scenes").json()]
    assert "whitted" in names
    assert "whitted_depth1" in names
    assert client.get("/api/scenes/whitted").json() == scene_dict("whitted")
    assert client.get("/api/scenes/nope").status_code == 404
    assert client.get("/api/scenes/..%2Fpyproject").status_code == 404
    # previews are rendered by workers, never in the API process: without one, a preview waits, and says so
    png = client.get("/api/scenes/phong/preview.png")
    assert png.status_code == 503
    assert png.headers["retry-after"] == "2"
    assert png.json()["errors"] == [
        {"path": "name", "message": "the preview of 'phong' waits for a render worker; try again in a moment"}
    ]
    assert client.get("/api/scenes").json()[names.index("phong")]["preview"]["state"] == "queued"
    jobs = client.get("/api/jobs?kind=preview", headers=bearer(INSTRUCTOR)).json()["jobs"]
    assert [j["name"] for j in jobs] == ["preview of phong"]
    assert client.delete(f"/api/jobs/{jobs[0]['id']}", headers=bearer(INSTRUCTOR)).status_code == 200
    page = client.get("/")
    assert page.status_code == 200
    assert "/api/scenes" in page.text


def test_api_tools_validate_reports_paths(client):
    bad = scene_dict("whitted")
    bad["objects"][2]["radius"] = -1
    r = client.post("/api/validate", json={"scene": bad})
    assert r.status_code == 200
    body = r.json()
    assert body["valid"] is False
    assert body["errors"][0]["path"] == "objects[2].radius"
    assert client.post("/api/validate", json={"scene": scene_dict("whitted")}).json()["valid"] is True


def test_api_tools_raytree_needs_a_worker(client):
    """Ray trees are traced by workers, never in the API process: without one, a clear 503 at once."""
    scene = small(scene_dict("whitted"), 32, 24)
    r = client.post("/api/raytree", json={"scene": scene, "x": 21, "y": 13})
    assert r.status_code == 503
    assert "no render worker takes interactive work" in r.json()["errors"][0]["message"]
    bad = client.post("/api/raytree", json={"scene": scene, "x": 99, "y": 0})  # checked before any worker
    assert bad.status_code == 422
    assert bad.json()["errors"][0]["path"] == "x"


def test_api_tools_raytree_sample_out_of_range_is_refused_before_any_job(client):
    """Sample 16 of a 16-spp scene (and a point of an adaptive grid past its last) is a 422 at `sample` before
    anything is queued: no job is made to fail in a worker (health would count it as a failed job)."""
    scene = small(scene_dict("whitted"), 32, 24, sampler={"type": "jittered", "spp": 16})
    adaptive = small(scene_dict("whitted"), 32, 24, sampler={"type": "adaptive", "max_level": 1})
    before = client.get("/api/health").json()["jobs"]
    for sc, sample, last in ((scene, 16, 15), (scene, -1, 15), (adaptive, 25, 24)):
        r = client.post("/api/raytree", json={"scene": sc, "x": 1, "y": 1, "sample": sample})
        assert r.status_code == 422, r.text
        assert r.json()["errors"] == [{"path": "sample", "message": f"must be a sample index in 0..{last}"}]
    assert client.get("/api/health").json()["jobs"] == before


def test_api_tools_api_docs_load_nothing_from_other_hosts(client):
    """Swagger UI comes from our own server, so the page's "API" link works offline; /redoc is off (ReDoc's
    bundle fetches its maker's logo from a CDN)."""
    import re

    page = "/docs"
    assert client.get("/redoc").status_code == 404
    html = client.get(page)
    assert html.status_code == 200
    assert not re.search(r"(https?:)?//[a-z0-9.-]+\.[a-z]{2,}", html.text, re.I), "an external host in " + page
    assets = re.findall(r'(?:src|href)="([^"]+)"', html.text)
    assert assets
    assert all(a.startswith("/") for a in assets)
    assert any(a.endswith(".js") for a in assets)
    for url in assets:
        assert client.get(url).status_code == 200, url
    assert any(a.endswith(".css") for a in assets)
    assert "'/openapi.json'" in html.text
    assert client.get("/openapi.json").status_code == 200
