"""A ready render worker and a ready checking process have imported the mesh reader (trimesh, with the parts of
scipy it takes: 0.8-1.5 s), so that no student's first scene with a mesh file waits for it (issue #25: the
texture lesson's first panel took 3.1 s against 0.3 s for the second). Seen from outside: the libraries
each process has mapped (/proc/PID/maps), once the server says it is ready."""

from __future__ import annotations

from pathlib import Path

from tests.support.api import api_client, wait_for

MARK = "/scipy/sparse/csgraph/"  # trimesh's graph module imports scipy.sparse.csgraph, a compiled library


def mapped(pid: int) -> str:
    return Path(f"/proc/{pid}/maps").read_text()


def test_worker_warm_workers_and_checkers_hold_the_mesh_reader_once_ready(tmp_path):
    with api_client(tmp_path / "data", workers=1) as client:  # its render workers ready
        health = client.get("/api/health").json()
        pids = [w["pid"] for w in health["workers"]]

        def checkers_ready() -> list[int] | None:  # they start beside the workers (a CI run met one "starting")
            checkers = client.app.state.checks.info()
            return [c["pid"] for c in checkers] if all(c["state"] != "starting" for c in checkers) else None

        pids += wait_for(checkers_ready, 120, "the checking processes ready")
        assert len(pids) >= 2, health
        for pid in pids:
            assert MARK in mapped(pid), f"process {pid} has not imported the mesh reader"
