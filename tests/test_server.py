"""The tool and example routes through the TestClient (the jobs: test_api_*.py)."""

import json

import pytest
from conftest import scene_dict, small
from fastapi.testclient import TestClient

from server.main import create_app
from server.settings import Settings


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    settings = Settings(data_dir=tmp_path_factory.mktemp("data"), workers=0)
    with TestClient(create_app(settings)) as c:
        yield c


def test_server_health_schema_and_scenes(client):
    health = client.get("/api/health").json()
    assert health["status"] == "ok" and health["workers"] == [] and health["jobs"]["queued"] == 0
    schema = client.get("/api/schema").json()
    assert "properties" in schema and "camera" in schema["properties"]
    names = [s["name"] for s in client.get("/api/scenes").json()]
    assert "whitted" in names and "whitted_depth1" in names
    assert client.get("/api/scenes/whitted").json() == scene_dict("whitted")
    assert client.get("/api/scenes/nope").status_code == 404
    assert client.get("/api/scenes/..%2Fpyproject").status_code == 404
    png = client.get("/api/scenes/phong/preview.png")
    assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"
    page = client.get("/")
    assert page.status_code == 200 and "/api/scenes" in page.text


def test_server_validate_reports_paths(client):
    bad = scene_dict("whitted")
    bad["objects"][2]["radius"] = -1
    r = client.post("/api/validate", json={"scene": bad})
    assert r.status_code == 200
    body = r.json()
    assert body["valid"] is False and body["errors"][0]["path"] == "objects[2].radius"
    assert client.post("/api/validate", json={"scene": scene_dict("whitted")}).json()["valid"] is True


def test_server_raytree_matches_the_library(client):
    from tracer.raytree import ray_tree
    from tracer.scene import load_scene

    scene = small(scene_dict("whitted"), 32, 24)
    r = client.post("/api/raytree", json={"scene": scene, "x": 21, "y": 13, "sample": 2})
    assert r.status_code == 200
    assert r.json() == json.loads(json.dumps(ray_tree(load_scene(scene)[0], 21, 13, 2)))
    bad = client.post("/api/raytree", json={"scene": scene, "x": 99, "y": 0})
    assert bad.status_code == 422 and bad.json()["errors"][0]["path"] == "x"
    missing = client.post("/api/raytree", json={"scene": scene})
    assert missing.status_code == 422 and {e["path"] for e in missing.json()["errors"]} == {"x", "y"}


def test_server_settings_from_the_environment_and_a_file(tmp_path, monkeypatch):
    from server.settings import load_settings

    conf = tmp_path / "service.env"
    conf.write_text("TRACER_MAX_SPP=256\nTRACER_MAX_JOB_SECONDS=30\nTRACER_WORKERS=3\n")
    monkeypatch.setenv("TRACER_MAX_SPP", "64")  # the environment wins over the file
    monkeypatch.setenv("TRACER_SETTINGS_FILE", str(conf))
    s = load_settings(workers=2)  # and arguments (the command line) over both
    assert (s.max_spp, s.max_job_seconds, s.workers) == (64, 30.0, 2)
    assert s.limits.max_spp == 64
    with pytest.raises(FileNotFoundError):
        load_settings(tmp_path / "missing.env")


def test_server_worker_line_wakes_readies_and_stops():
    """The server's line to a worker (a socket pair, no semaphores): wake, ready, and close = stop."""
    import multiprocessing as mp
    import time

    from server.channel import ServerEnd, WorkerEnd

    ours, theirs = mp.get_context("spawn").Pipe()
    server, worker = ServerEnd(ours), WorkerEnd(theirs)
    assert not server.is_ready()
    worker.ready()
    assert server.is_ready() and server.is_ready()  # it stays ready
    for _ in range(100_000):  # a busy worker's wakes pile up: never blocking the API
        server.wake()
    start = time.monotonic()
    worker.wait(5.0)  # pending wakes: returns at once, and drains them
    assert time.monotonic() - start < 1.0 and not worker.stopping()
    start = time.monotonic()
    worker.wait(0.2)  # none pending: the full timeout
    assert time.monotonic() - start >= 0.19
    server.close()
    assert worker.stopping()
    server.wake()  # after close: nothing happens (never a write to a reused descriptor)
    start = time.monotonic()
    worker.wait(5.0)  # a stopping worker does not sleep
    assert time.monotonic() - start < 1.0
    theirs.close()


def test_server_api_docs_load_nothing_from_other_hosts(client):
    """Swagger UI comes from our own server, so the page's "API" link works offline; /redoc is off (ReDoc's
    bundle fetches its maker's logo from a CDN)."""
    import re

    page = "/docs"
    assert client.get("/redoc").status_code == 404
    html = client.get(page)
    assert html.status_code == 200
    assert not re.search(r"(https?:)?//[a-z0-9.-]+\.[a-z]{2,}", html.text, re.I), "an external host in " + page
    assets = re.findall(r'(?:src|href)="([^"]+)"', html.text)
    assert assets and all(a.startswith("/") for a in assets)
    assert any(a.endswith(".js") for a in assets)
    for url in assets:
        assert client.get(url).status_code == 200, url
    assert any(a.endswith(".css") for a in assets)
    assert "'/openapi.json'" in html.text and client.get("/openapi.json").status_code == 200
