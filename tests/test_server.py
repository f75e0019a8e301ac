"""The first HTTP routes, through the TestClient and through a real uvicorn on loopback."""

import json
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest
from conftest import ROOT, scene_dict, small
from fastapi.testclient import TestClient

from server.main import create_app
from server.settings import Settings


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    settings = Settings()
    settings.data_dir = tmp_path_factory.mktemp("data")
    with TestClient(create_app(settings)) as c:
        yield c


def test_server_health_schema_and_scenes(client):
    assert client.get("/api/health").json() == {"status": "ok"}
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


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_server_real_uvicorn_on_loopback(tmp_path):
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "server", "--port", str(port), "--data-dir", str(tmp_path)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.time() + 120
        while True:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/health", timeout=2) as r:
                    assert json.load(r) == {"status": "ok"}
                    break
            except (urllib.error.URLError, ConnectionError):
                assert proc.poll() is None, proc.stdout.read().decode()
                assert time.time() < deadline, "server did not start"
                time.sleep(0.3)
        req = urllib.request.Request(
            f"http://127.0.0.1:{port}/api/validate",
            method="POST",
            data=b'{"scene": {"camera": {"lookfrom": [0, 0, NaN]}}}',
            headers={"content-type": "application/json"},
        )
        with urllib.request.urlopen(req, timeout=10) as r:
            body = json.load(r)
        # the literal NaN reaches the validator, which names its field (no 500 serialising it)
        assert body["valid"] is False
        assert "camera.lookfrom[2]" in [e["path"] for e in body["errors"]]
    finally:
        proc.terminate()
        proc.wait(timeout=20)
