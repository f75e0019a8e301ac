"""GET /api/status: the server's status for its operator (server/api/routes/status.py, docs/service.md "The status
page"), the admin's alone; each fact read from where it lives: the worker and its host from the queue, the lanes
from the job store, the grades going back from the LMS's rows, the last backup from what `python -m server backup`
left in the data directory, the disk from the janitor's last round against TRACER_MAX_DATA_BYTES, the version from
the package and the schema from the database. The app's clock is a `Clock` (the backup's age follows it)."""

from __future__ import annotations

import tomllib
from datetime import UTC, datetime, timedelta

import pytest

from server.core.backup import backup
from server.core.migrations import LATEST
from server.course.lms_store import LmsStore
from tests.support.api import INSTRUCTOR, Clock, bearer, long_scene, submit, wait_for
from tests.support.scene import ROOT

T0 = datetime(2026, 12, 7, 6, 0, tzinfo=UTC)
ADMIN = bearer(INSTRUCTOR)
LIMIT = 50_000_000


@pytest.fixture(scope="module")
def app_client(tmp_path_factory):
    from tests.support.api import api_client

    data = tmp_path_factory.mktemp("status") / "data"
    with api_client(data, workers=1, instructor_token=INSTRUCTOR, max_data_bytes=LIMIT) as c:
        c.app.state.clock = Clock(T0)
        yield c


def test_api_status_is_the_admin_s(app_client):
    assert app_client.get("/api/status").status_code == 401  # a student's token
    assert app_client.get("/api/status", headers={"Authorization": ""}).status_code == 401
    r = app_client.get("/status")  # the page itself is a shell: it asks for the token and reads the JSON
    assert r.status_code == 200
    assert "text/html" in r.headers["content-type"]
    assert "/js/status.js" in r.text


def test_api_status_shows_workers_lanes_release_schema_and_disk(app_client):
    s = app_client.get("/api/status", headers=ADMIN).json()
    assert s["time"] == T0.isoformat()
    assert s["version"] == tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert s["schema"] == {"version": LATEST, "latest": LATEST}
    assert s["backend"] == "embedded"
    ((worker),) = s["workers"]
    assert worker["alive"]
    assert worker["ready"]
    assert worker["host"]
    assert s["hosts"] == [{"host": worker["host"], "workers": 1, "alive": 1, "ready": 1, "busy": 0, "devices": ["cpu"]}]
    assert s["queue"] == {"interactive": {"queued": 0, "running": 0}, "batch": {"queued": 0, "running": 0}}
    disk = s["disk"]  # the janitor's round at start-up measured it
    assert disk["limit_bytes"] == LIMIT
    assert 0 < disk["used_bytes"] < LIMIT
    assert disk["free_bytes"] > 0
    assert disk["share"] == pytest.approx(disk["used_bytes"] / LIMIT) and disk["near"] is False
    assert disk["measured_at"] is not None

    # a long render takes the worker, a second waits in the batch lane
    first, second = submit(app_client, long_scene(4096)), submit(app_client, long_scene(4096))
    try:
        wait_for(lambda: app_client.get(f"/api/jobs/{first['id']}").json()["status"] == "running", 60, "a running job")
        s = app_client.get("/api/status", headers=ADMIN).json()
        lanes = s["queue"]
        assert lanes["interactive"]["running"] + lanes["batch"]["running"] == 1
        assert lanes["interactive"]["queued"] + lanes["batch"]["queued"] == 1
        assert s["hosts"][0]["busy"] == 1
        assert s["workers"][0]["job"] == first["id"]
    finally:
        for j in (second, first):
            app_client.delete(f"/api/jobs/{j['id']}")
    wait_for(lambda: app_client.get(f"/api/jobs/{first['id']}").json()["status"] == "cancelled", 60, "the cancel")


def test_api_status_shows_the_last_backup_and_its_age(app_client, tmp_path):
    data = app_client.app.state.settings.data_dir
    b = app_client.get("/api/status", headers=ADMIN).json()["backup"]
    assert b == {"time": None, "age_seconds": None, "dest": None, "bytes": None, "old": True}  # none yet

    manifest = backup(data, tmp_path / "nightly", clock=lambda: T0 - timedelta(hours=3))
    b = app_client.get("/api/status", headers=ADMIN).json()["backup"]
    assert b["time"] == (T0 - timedelta(hours=3)).isoformat() and b["age_seconds"] == 3 * 3600
    assert b["dest"] == str((tmp_path / "nightly").resolve()) and b["old"] is False
    assert b["bytes"] == manifest["database"]["bytes"] + sum(f["bytes"] for f in manifest["files"].values())
    assert "last-backup.json" not in manifest["files"]  # the record is the data directory's own

    app_client.app.state.clock.now = T0 + timedelta(days=2)  # the nightly backup stopped two days ago
    try:
        b = app_client.get("/api/status", headers=ADMIN).json()["backup"]
        assert b["old"] is True
        assert b["age_seconds"] == 2 * 86400 + 3 * 3600
    finally:
        app_client.app.state.clock.now = T0


def test_api_status_counts_the_grades_going_back_to_the_lms(app_client):
    app_client.app.state.lms.stop()  # the poster would post these rows (to a platform that is not registered)
    store = LmsStore(app_client.app.state.settings.data_dir)
    now = T0.timestamp()
    row = {"platform_id": "p1", "lineitem": "L", "assignment_id": "a", "student": "s", "score_max": 10.0}
    for i in range(4):
        assert store.add_score({**row, "user_id": f"u{i}", "score_given": float(i)}, now - 600)
    rows = store.due(now, 10)
    store.sent(rows[0]["id"], now)
    store.failed(rows[1]["id"], "the platform answered 503", now + 60)
    store.refused(rows[3]["id"], 404, "the score: the platform answered HTTP 404 (Not Found)", now)
    lms = app_client.get("/api/status", headers=ADMIN).json()["lms"]
    assert (lms["pending"], lms["failed"], lms["sent"], lms["refused"]) == (2, 1, 1, 1)
    assert lms["last_error"]["message"] == "the platform answered 503"
    assert lms["last_error"]["platform_id"] == "p1"
    assert lms["last_error"]["next_try"] == datetime.fromtimestamp(now + 60, UTC).isoformat()
    assert lms["oldest_pending_seconds"] == pytest.approx(600)
