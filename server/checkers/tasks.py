"""What a checking process does (started by server/checkers/pool.py): each task takes plain data (a request's
body as bytes, the limits) and answers plain data (errors, warnings, what the route needs of the scene)."""

from __future__ import annotations

import json
import logging
import os
import signal
from pathlib import Path

from server.core import children
from server.core.exits import exit_now
from tracer.scene import Limits, SceneError, load_scene

log = logging.getLogger(__name__)


def _scene_of(body: bytes, limits: Limits, assets: Path) -> tuple:
    """The request body's scene, validated as POST /api/jobs validates it (the format, the limits, the asset
    files): (Scene, warnings), or raises SceneError."""
    data = json.loads(body)["scene"]  # the body was checked by the route's model: an object with a scene
    return (*load_scene(data, limits, assets=assets), data)


def validate(body: bytes, limits: Limits, assets: Path) -> dict:
    """POST /api/validate's answer."""
    try:
        _, warnings, _ = _scene_of(body, limits, assets)
    except SceneError as exc:
        return {"valid": False, "errors": exc.errors, "warnings": []}
    return {"valid": True, "errors": [], "warnings": warnings}


def summary(body: bytes, limits: Limits, assets: Path, threads: int) -> dict:
    """What POST /api/jobs and POST /api/raytree need of a valid scene (the scene's JSON text, its size and
    estimates), or its `errors`."""
    from tracer.rendering import estimate
    from tracer.rendering.raytree import sample_count

    try:
        scene, warnings, data = _scene_of(body, limits, assets)
    except SceneError as exc:
        return {"errors": exc.errors}
    solve = estimate.solve_seconds(scene, threads, assets)
    return {
        "text": json.dumps(data), "warnings": warnings, "name": scene.name, "width": scene.film.width,
        "height": scene.film.height, "spp": scene.sampler.spp, "samples": sample_count(scene),
        "integrator": scene.render.integrator,
        "seconds": estimate.seconds(scene, threads, assets, solve, limits), "solve_seconds": solve,
    }  # fmt: skip


def samples(body: bytes, limits: Limits, assets: Path, x: int, y: int) -> dict:
    """POST /api/samples's answer, or its `errors`."""
    from tracer.kernels.compile import compile_scene
    from tracer.tools.pixel_samples import pixel_samples

    try:
        scene, _, _ = _scene_of(body, limits, assets)
        # as many positions as a scene may have samples (the service's max_spp), the adaptive grid's included
        return {"samples": pixel_samples(compile_scene(scene, assets, limits=limits), x, y, max_samples=limits.max_spp)}
    except SceneError as exc:
        return {"errors": exc.errors}


def read(body: bytes) -> tuple:
    """A request body's JSON for the route's own model (server/api/models.py): ("ok", the body with its scene's
    content left out), or why it is not JSON as the API would have said it: ("invalid", message, position)
    for a JSON syntax error, ("undecodable", encoding, start, end, reason) for bytes that are not text in the
    encoding JSON's first bytes name (UTF-8 but for a body that starts with a zero byte), ("unreadable",
    message) for the rest (an integer too long, nesting too deep for the parser)."""
    try:
        data = json.loads(body)
    except json.JSONDecodeError as exc:
        return "invalid", exc.msg, exc.pos
    except UnicodeDecodeError as exc:
        return "undecodable", exc.encoding, exc.start, exc.end, exc.reason
    except (ValueError, RecursionError) as exc:
        return "unreadable", f"{type(exc).__name__}: {exc}"
    if isinstance(data, dict) and isinstance(data.get("scene"), dict):
        data = {**data, "scene": {}}  # a scene is read, from the same bytes, where it is checked
    return "ok", data


def loaded(answer: tuple, body: bytes):
    """`read`'s answer as json.loads would have given it: the data, or its exception (the same error answer)."""
    if answer[0] == "invalid":
        raise json.JSONDecodeError(answer[1], body.decode(json.detect_encoding(body), "surrogatepass"), answer[2])
    if answer[0] == "undecodable":
        raise UnicodeDecodeError(answer[1], body, *answer[2:])
    if answer[0] == "unreadable":
        raise ValueError(answer[1])
    return answer[1]


TASKS = {"read": read, "validate": validate, "summary": summary, "samples": samples}


def checker_main(conn, nice: int, server: int, mesh_reader: bool = True) -> None:
    """A checking process (forked from the server's forkserver, server/core/children.py): below the API in
    priority, deaf to the terminal's Ctrl-C and to a SIGTERM sent to the server's whole process group (the server
    stops it: closing its line), gone with its server; loads the kernels of the samples from Warp's cache, says it
    is ready, then answers tasks (name, args) until its line closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if nice:
        try:
            os.nice(nice)
        except OSError:
            pass
    children.watch_server(server)
    from tracer.assets import import_mesh_reader
    from tracer.tools.pixel_samples import load_kernels

    load_kernels()
    if mesh_reader:
        import_mesh_reader()  # a scene's mesh files are read here first (their triangles counted)
    conn.send("ready")
    while True:
        try:
            name, args = conn.recv()
        except (EOFError, OSError):
            exit_now()  # its server closed the line: nothing of ours is left to keep
        try:
            answer = ("ok", TASKS[name](*args))
        except Exception as exc:  # a bug must answer the request (a 500 in the API), not end the process
            log.exception("scene check %s failed", name)
            answer = ("crash", f"{type(exc).__name__}: {exc}")
        conn.send(answer)
