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


def test_worker_warm_without_the_preload_a_mesh_scene_imports_the_reader_when_it_comes(tmp_path):
    """TRACER_PRELOAD_MESH_READER=0 (the tests' servers: tests/support/api.py): no process of the server maps the mesh
    reader once ready, and a scene with mesh files is checked and rendered all the same, its worker importing the
    reader then."""
    from tests.support.api import Server, small, submit, wait_finished
    from tests.support.scene import scene_dict

    with Server(tmp_path / "data", workers=1, env={"TRACER_PRELOAD_MESH_READER": "0"}) as server:
        (worker,) = server.worker_pids()

        def checkers() -> list[int] | None:
            found = server.client.get("/api/health").json()["checkers"]
            return [c["pid"] for c in found] if found and all(c["pid"] for c in found) else None

        for pid in [worker, *wait_for(checkers, 120, "the checking processes ready")]:
            assert MARK not in mapped(pid), f"process {pid} imported the mesh reader at its start"
        meshes = small(scene_dict("meshes"), 24, 18, sampler={"type": "jittered", "spp": 1})
        done = wait_finished(server.client, submit(server.client, meshes)["id"], timeout=120)
        assert done["status"] == "done", done
        assert server.client.get(done["image_url"]).status_code == 200
        assert MARK in mapped(worker), "the worker rendered meshes without the mesh reader?"
