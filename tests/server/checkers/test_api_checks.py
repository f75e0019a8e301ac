"""Scene checks off the event loop (server/checkers/pool.py): POST /api/validate, the scenes of POST /api/jobs and
POST /api/raytree, and POST /api/samples are checked in a pool of processes, with a time limit, a bound on
the requests waiting, and the process of a client that went away stopped; large bodies are read there too,
with the answers of the API's own parser. Through the shared apps of conftest.py, and a real server on
loopback for a client that goes away."""

from __future__ import annotations

import json
import os
import socket

import pytest

from tests.support.api import Server, pid_alive, wait_for
from tests.support.assets import big_png_uri, gltf_instanced, gltf_uri
from tests.support.scene import scene_dict, small
from tracer.scene import validate_scene


def spheres(n: int) -> dict:
    """A scene of n small spheres in a row of rows, one named material: large to check (25 000 spheres are
    1.6 MB of compact JSON and a fifth of a second of validation)."""
    side = int(n**0.5) + 1
    objects = [{"type": "sphere", "center": [k % side, 0, k // side], "radius": 0.4, "material": "m"} for k in range(n)]
    scene = {"camera": {"lookfrom": [0, 60, 120], "lookat": [0, 0, 0]}, "film": {"width": 32, "height": 32}}
    return {**scene, "materials": {"m": {"kd": 0.6}}, "objects": objects}


def compact(body: dict) -> bytes:
    return json.dumps(body, separators=(",", ":")).encode()


def post(client, url: str, body: bytes):
    return client.post(url, content=body, headers={"content-type": "application/json"})


def cpu_seconds(pid: int) -> float:
    """User and system CPU time of a process so far (/proc/PID/stat)."""
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def peak_rss(pid: int) -> int:
    """The most memory the process has held at once (VmHWM, bytes)."""
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no VmHWM")


def checkers(client) -> list[dict]:
    return client.get("/api/health").json()["checkers"]


def ready(client) -> list[dict]:
    """The checking processes, once every one is started and idle."""

    def idle() -> list[dict] | None:
        found = checkers(client)
        return found if all(c["state"] == "idle" for c in found) else None

    return wait_for(idle, 60, "the checking processes to be idle")


@pytest.fixture
def client(client_without_workers):
    return client_without_workers


def test_api_checks_validation_runs_in_the_checking_processes(client):
    """Validating 25 000 spheres costs the checking processes its CPU time, not the API process; the answer is
    the library's."""
    pool = ready(client)
    assert len(pool) == 2 and all(c["pid"] != os.getpid() and pid_alive(c["pid"]) for c in pool)
    scene = spheres(25_000)
    before = sum(cpu_seconds(c["pid"]) for c in pool)
    r = post(client, "/api/validate", compact({"scene": scene}))
    assert r.status_code == 200 and r.json() == validate_scene(scene)
    assert sum(cpu_seconds(c["pid"]) for c in pool) - before >= 0.05  # a fifth of a second, give or take
    bad = scene_dict("whitted")
    bad["objects"][2]["radius"] = -1
    r = client.post("/api/validate", json={"scene": bad})
    assert r.json()["errors"] == [{"path": "objects[2].radius", "message": "must be > 0"}]
    assert [c["pid"] for c in ready(client)] == [c["pid"] for c in pool]  # the same processes, idle again


def test_api_checks_a_6000_x_6000_data_image_is_refused_by_every_scene_route_without_decoding(client):
    """A blank 6000 x 6000 PNG in a data: URI (a 100 KB request; 432 MB as float32 once decoded) is refused from
    its header by validate, jobs, ray tree and samples alike, at its field; neither the API process nor a
    checking process grows by more than a few tens of MB doing it."""
    pool = ready(client)
    pids = [os.getpid(), *(c["pid"] for c in pool)]
    before = {pid: peak_rss(pid) for pid in pids}
    scene = small(scene_dict("texture"), 32, 24)
    scene["materials"]["big"] = {"texture": {"type": "image", "file": big_png_uri()}}
    scene["objects"][0]["material"] = "big"
    error = {
        "path": "materials.big.texture.file",
        "message": "the image is 6000x6000 = 36000000 pixels; must be at most 16777216 (limit max_texture_pixels)",
    }
    r = client.post("/api/validate", json={"scene": scene})
    assert r.status_code == 200
    assert r.json() == {"valid": False, "errors": [error], "warnings": []}
    for url, extra in (("/api/jobs", {}), ("/api/raytree", {"x": 1, "y": 1}), ("/api/samples", {"x": 1, "y": 1})):
        r = client.post(url, json={"scene": scene, **extra})
        assert r.status_code == 422 and r.json() == {"errors": [error]}, (url, r.text)
    grown = {pid: peak_rss(pid) - before[pid] for pid in pids}
    assert max(grown.values()) < 64_000_000, f"peak memory grew by {grown} bytes"


def test_api_checks_instanced_gltf_meshes_are_refused_from_their_node_tree_holding_nothing(client):
    """The issue's glTF: 1000 nodes sharing one 5000-triangle mesh, a 233 KB data: URI that trimesh built into
    5 million triangles (a checking process reached 766 MB for one, and kept each in its mesh cache: 1468 MB
    after four). Four different ones, through validate and jobs, are refused at the mesh's field from the
    counts in their JSON (trimesh is not even imported); no checking process grows by more than a few MB."""
    pool = ready(client)
    for _ in pool:  # the scene without the mesh first: what a first check costs a process is not the mesh's
        r = client.post("/api/validate", json={"scene": small(scene_dict("texture"), 32, 24)})
        assert r.json()["valid"]
    before = {c["pid"]: peak_rss(c["pid"]) for c in pool}
    for k in range(4):
        tree = gltf_instanced(1000, grid=50)
        tree["nodes"][0]["translation"] = [float(k), 0.0, 0.0]  # another file, another key in the mesh cache
        scene = small(scene_dict("texture"), 32, 24)
        scene["objects"].append({"type": "mesh", "file": gltf_uri(tree), "material": scene["objects"][0]["material"]})
        error = {
            "path": f"objects[{len(scene['objects']) - 1}].file",
            "message": "the data: URI makes 5000000 triangles (1000 mesh instances in its node tree); "
            "must be at most 2000000 (limit max_primitives)",
        }
        r = client.post("/api/validate", json={"scene": scene})
        assert r.status_code == 200
        assert r.json() == {"valid": False, "errors": [error], "warnings": []}
        r = client.post("/api/jobs", json={"scene": scene})
        assert r.status_code == 422 and r.json() == {"errors": [error]}, r.text
    grown = {pid: peak_rss(pid) - before[pid] for pid in before}
    assert max(grown.values()) < 16_000_000, f"peak memory grew by {grown} bytes"


def test_api_checks_a_check_past_its_time_limit_is_stopped_and_its_process_replaced(client, settings):
    """Past TRACER_MAX_VALIDATE_SECONDS a check is stopped: its process is killed and a new one started; the
    scene is not valid (POST /api/validate), refused (422, POST /api/jobs), with the limit named."""
    pool = ready(client)
    settings.max_validate_seconds = 0.001
    body = compact({"scene": spheres(25_000)})
    message = (
        "checking the scene took longer than the limit of 0.001 s (TRACER_MAX_VALIDATE_SECONDS): it is too large "
        "to check; make it smaller"
    )
    r = post(client, "/api/validate", body)
    assert r.status_code == 200
    assert (r.json() == {"valid": False, "errors": [{"path": "", "message": message}],
                                                 "warnings": []})  # fmt: skip
    r = post(client, "/api/jobs", body)
    assert r.status_code == 422
    assert r.json() == {"errors": [{"path": "", "message": message}]}
    settings.max_validate_seconds = 10
    after = ready(client)
    assert sum(c["restarts"] for c in after) == sum(c["restarts"] for c in pool) + 2
    gone = {c["pid"] for c in pool} - {c["pid"] for c in after}
    assert gone and not any(pid_alive(pid) for pid in gone)
    assert post(client, "/api/validate", body).json()["valid"] is True


def test_api_checks_large_bodies_read_in_a_checking_process_get_the_parser_s_answers(client):
    """A body of more than 64 KB is parsed in a checking process: a JSON syntax error, a bare scene, a field the
    route does not know and a body that is not UTF-8 get the answers the API's own parser gives."""
    scene = spheres(2000)
    text = compact({"scene": scene}).decode()
    assert len(text) > 65536
    cut = text[:-1] + ","  # the last brace replaced: a syntax error at the end
    try:
        json.loads(cut)
    except json.JSONDecodeError as e:
        where = f"line {e.lineno}, column {e.colno}: {e.msg}"
    r = post(client, "/api/validate", cut.encode())
    assert r.status_code == 422
    assert r.json() == {"errors": [{"path": "", "message": f"invalid JSON at {where}"}]}
    r = post(client, "/api/validate", compact(scene))
    assert r.status_code == 422
    assert r.json()["errors"][0]["message"].startswith(
        'the scene must be sent inside the request as {"scene": {...}}; this body has the scene\'s own fields '
        "(camera, objects, materials, ...)"
    )
    r = post(client, "/api/raytree", compact({"scene": scene, "x": 1, "y": "one", "colour": 1}))
    assert r.status_code == 422
    assert {e["path"] for e in r.json()["errors"]} == {"y", "colour"}
    r = post(client, "/api/jobs", b'{"scene": {"name": "\xff\xfe"}, "pad": "' + b"x" * 70000 + b'"}')
    assert r.status_code == 400
    small_one = post(client, "/api/jobs", b'{"scene": {"name": "\xff\xfe"}}')
    assert r.json() == small_one.json()  # the same answer as the API's own parser gives a small body


def test_api_checks_a_client_that_goes_away_stops_its_check_and_the_waiting_line_is_bounded(tmp_path):
    """`python -m server` with one checking process and no request allowed to wait: while a client's 200 000
    spheres are being validated, another request is answered 429; when that client closes its connection,
    the process checking its scene is killed (no CPU burning for an answer nobody reads) and a new one
    takes its place."""
    env = {"TRACER_VALIDATE_PROCESSES": "1", "TRACER_MAX_VALIDATE_WAITING": "0", "TRACER_MAX_BODY_BYTES": "40000000"}
    with Server(tmp_path / "data", workers=0, env=env) as server:
        (first,) = ready(server.client)
        body = compact({"scene": spheres(200_000)})
        head = "POST /api/validate HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        head += f"Content-Length: {len(body)}\r\n\r\n"
        with socket.create_connection(("127.0.0.1", server.port)) as gone:
            gone.sendall(head.encode() + body)
            wait_for(lambda: checkers(server.client)[0]["task"] == "validate", 60, "the scene being validated")
            r = server.client.post("/api/validate", json={"scene": scene_dict("whitted")})
            assert r.status_code == 429
            assert r.headers["retry-after"] == "2"
            assert "TRACER_MAX_VALIDATE_WAITING" in r.json()["errors"][0]["message"]
        # the client has gone: its check is stopped, by killing the process (it had seconds of work left)
        (after,) = wait_for(lambda: (c := checkers(server.client))[0]["restarts"] == 1 and c, 30, "the checker killed")
        wait_for(lambda: not pid_alive(first["pid"]), 30, "the old checking process to end")
        (after,) = ready(server.client)
        assert after["pid"] != first["pid"]
        assert server.client.post("/api/validate", json={"scene": scene_dict("whitted")}).json()["valid"] is True
        assert "scene check stopped: the client went away" in server.log_text()


class CheckerLine:
    """A CheckPool of one checker and no processes, its checker busy: `take(name)` waits in its line (a small
    body's when the name starts with "small") and records the name once served; `free()` frees the checker."""

    @staticmethod
    async def stays() -> bool:  # the client never goes away
        return False

    def __init__(self, tmp_path):
        from server.checkers.pool import CheckPool
        from server.core.settings import Settings

        self.pool = CheckPool(Settings(data_dir=tmp_path, validate_processes=1))
        self.checker = self.pool.checkers[0]
        self.checker.state = "busy"
        self.served: list[str] = []

    async def take(self, name: str) -> None:
        await self.pool._take(self.stays, size=100 if name.startswith("small") else 100_000)
        self.served.append(name)

    def free(self) -> None:
        with self.pool._lock:
            self.checker.state = "idle"
            self.pool._wake()


def test_checks_waiting_requests_are_served_first_come_first_served(tmp_path):
    """The waiting line of CheckPool._take (no processes: its checkers' states are set by hand): requests that
    wait take a freed checker in the order they came, and a newcomer does not take one before them."""
    import anyio

    line = CheckerLine(tmp_path)
    pool, served, take, free = line.pool, line.served, line.take, line.free

    async def main() -> None:
        async with anyio.create_task_group() as tg:
            for name in "abc":
                tg.start_soon(take, name)
                await anyio.sleep(0.05)  # in line in this order
            assert len(pool._waiters) == 3
            assert served == []
            free()
            tg.start_soon(take, "newcomer")  # comes while the freed checker is handed to the first in line
            await anyio.sleep(0.05)
            for _ in range(3):
                free()
                await anyio.sleep(0.05)
            assert served == ["a", "b", "c", "newcomer"]
            assert not pool._waiters

    anyio.run(main)


def test_checks_a_small_body_s_request_passes_the_line_of_large_ones(tmp_path):
    """The two lines of CheckPool._take (no processes, states set by hand): with large bodies' requests
    waiting, a small body's request that comes later takes the next freed checker, a newcomer small one
    included; the large ones then keep their order."""
    import anyio

    line = CheckerLine(tmp_path)
    pool, checker, served, take, free = line.pool, line.checker, line.served, line.take, line.free

    async def main() -> None:
        async with anyio.create_task_group() as tg:
            for name in ["large 1", "large 2", "small 1", "large 3", "small 2"]:
                tg.start_soon(take, name)
                await anyio.sleep(0.05)  # in line in this order
            assert len(pool._waiters) == 3
            assert len(pool._small) == 2
            assert served == []
            for _ in range(2):
                free()
                await anyio.sleep(0.05)
            assert served == ["small 1", "small 2"]
            checker.state = "idle"
            tg.start_soon(take, "small 3")  # a checker is free, large ones wait: the small newcomer takes it
            await anyio.sleep(0.05)
            for _ in range(3):
                free()
                await anyio.sleep(0.05)
            assert served == ["small 1", "small 2", "small 3", "large 1", "large 2", "large 3"]
            assert not pool._waiters
            assert not pool._small

    anyio.run(main)


def test_checks_the_bodies_held_by_waiting_requests_are_bounded_in_bytes(tmp_path):
    """CheckPool._take counts the bodies of the requests waiting (no processes, states set by hand): past
    max_validate_waiting_bytes a request is answered 429 naming TRACER_MAX_VALIDATE_WAITING_BYTES, while a small
    one still fits; the count goes back to 0 as they are served."""
    import anyio

    from server.core.errors import TooMany

    line = CheckerLine(tmp_path)
    line.pool.settings = line.pool.settings.model_copy(update={"max_validate_waiting_bytes": 150_000})
    pool, served, take, free = line.pool, line.served, line.take, line.free

    async def main() -> None:
        async with anyio.create_task_group() as tg:
            tg.start_soon(take, "large 1")  # 100 000 bytes wait
            await anyio.sleep(0.05)
            with pytest.raises(TooMany) as refused:
                await take("large 2")  # 200 000 > 150 000
            assert refused.value.retry_after == 2
            assert "TRACER_MAX_VALIDATE_WAITING_BYTES" in str(refused.value.errors)
            tg.start_soon(take, "small 1")  # 100 100 bytes: it fits
            await anyio.sleep(0.05)
            assert pool._waiting_bytes == 100_100
            for _ in range(2):
                free()
                await anyio.sleep(0.05)
            assert served == ["small 1", "large 1"]
            assert pool._waiting_bytes == 0

    anyio.run(main)
