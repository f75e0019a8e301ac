"""A corpus of bad requests: every one gets a 4xx with `{"errors": [{path, message}]}`, never a 500.

The app here has no render worker (workers = 0): nothing is rendered, jobs that are accepted wait.
"""

from __future__ import annotations

import json

import pytest

from tests.support.api import api_client, tiny_scene
from tests.support.assets import no_repr, obj_uri, png_uri, uri
from tests.support.scene import ROOT, scene_dict

BAD_DIR = ROOT / "tests" / "bad_scenes"
EXPECTED = json.loads((BAD_DIR / "expected.json").read_text())
LIMITS = dict(max_width=512, max_height=512, max_pixels=512 * 400, max_spp=64, max_depth=8, max_light_samples=4)
LIMITS.update(max_primitives=20, max_body_bytes=100_000, max_json_depth=32)


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """An app with small limits (LIMITS) and no worker; a server error is an answer here, not an exception."""
    with api_client(tmp_path_factory.mktemp("errors-data"), raise_server_exceptions=False, **LIMITS) as c:
        yield c


@pytest.fixture(scope="module")
def library_limits(tmp_path_factory):
    """An app with the library's default limits, which the bad-scene corpus's messages quote."""
    import dataclasses

    from tracer.scene import Limits

    limits = dataclasses.asdict(Limits())
    with api_client(tmp_path_factory.mktemp("corpus-data"), raise_server_exceptions=False, **limits) as c:
        yield c


@pytest.fixture(scope="module")
def primitives_200(tmp_path_factory):
    """An app whose scenes may have at most 200 primitives (and the default body size limit)."""
    with api_client(tmp_path_factory.mktemp("primitives-data"), raise_server_exceptions=False, max_primitives=200) as c:
        yield c


def check_error(r, status: int | None = None) -> list[dict]:
    """A 4xx with a list of {path, message}, in plain JSON (no NaN), nothing else."""
    assert 400 <= r.status_code < 500, (r.status_code, r.text)
    if status is not None:
        assert r.status_code == status, r.text
    body = json.loads(r.text, parse_constant=lambda token: pytest.fail(f"{token} in an error answer"))
    assert set(body) == {"errors"} and body["errors"], body
    for e in body["errors"]:
        assert set(e) == {"path", "message"} and isinstance(e["path"], str) and e["message"], e
    return body["errors"]


def paths(r) -> list[str]:
    return [e["path"] for e in check_error(r)]


def post_raw(client, url: str, body: bytes, content_type: str = "application/json"):
    return client.post(url, content=body, headers={"content-type": content_type})


def with_scene(text: str, **extra) -> bytes:
    """A request body whose scene is the JSON text `text` (kept as written: NaN stays the literal NaN)."""
    rest = "".join(f', "{k}": {json.dumps(v)}' for k, v in extra.items())
    return f'{{"scene": {text}{rest}}}'.encode()


SCENE = json.dumps(tiny_scene())


def scene_with(path: list, literal: str) -> bytes:
    """The tiny scene with the value at `path` replaced by a JSON literal (NaN, Infinity, 1e999...)."""
    data = tiny_scene()
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = "@@VALUE@@"
    return with_scene(json.dumps(data).replace('"@@VALUE@@"', literal))


JSON = "application/json"
ID = "AAAAAAAAAAAAAAAAAAAAAA"  # the shape of a job id, but no job's


def case(name: str, body: bytes | None, status: int | None, want: list[str] | None, url: str = "/api/jobs", **kw):
    """One bad request: its body, the status it must get (None: any 4xx) and the error paths (None: any)."""
    method = kw.get("method", "POST" if body is not None else "GET")
    return pytest.param(method, url, body, kw.get("ctype", JSON if body is not None else None), status, want, id=name)


def with_fields(extra: str) -> bytes:
    """The tiny scene's request with more body fields written as raw JSON text."""
    return with_scene(SCENE)[:-1] + b", " + extra.encode() + b"}"


MESH_AT = '{{"type": "mesh", "file": "{}", "material": "red"}}'

CORPUS = [
    # malformed bodies
    case("truncated JSON", b'{"scene": {"camera": ', 422, [""]),
    case("trailing comma", b'{"scene": {},}', 422, [""]),
    case("not UTF-8", b'{"scene": "\xff\xfe"}', None, None),
    case("empty body", b"", 422, [""]),
    case("text body", SCENE.encode(), 422, [""], ctype="text/plain"),
    case("array body", b"[1, 2]", 422, [""]),
    # wrong types and unknown fields of the request
    case("scene missing", b'{"priority": 1}', 422, ["scene"]),
    case("scene a string", b'{"scene": "whitted"}', 422, ["scene"]),
    case("scene null", b'{"scene": null}', 422, ["scene"]),
    case("unknown body key", with_scene(SCENE, colour=1), 422, ["colour"]),
    case("priority a string", with_scene(SCENE, priority="high"), 422, ["priority"]),
    case("priority a float", with_scene(SCENE, priority=1.5), 422, ["priority"]),
    case("priority a bool", with_scene(SCENE, priority=True), 422, ["priority"]),
    case("priority too high", with_scene(SCENE, priority=10**6), 422, ["priority"]),
    case("raytree x a string", with_fields('"x": "1", "y": 0'), 422, ["x"], url="/api/raytree"),
    case("raytree out of range", with_fields('"x": 16, "y": -1'), 422, ["x", "y"], url="/api/raytree"),
    # the literal tokens NaN and Infinity: an error at their field, never a 500 serialising it
    case("priority NaN", with_fields('"priority": NaN'), 422, ["priority"]),
    case("NaN in a vector", scene_with(["camera", "lookfrom", 2], "NaN"), 422, ["camera.lookfrom[2]"]),
    case("Infinity radius", scene_with(["objects", 2, "radius"], "Infinity"), 422, ["objects[2].radius"]),
    case("-Infinity exposure", scene_with(["film", "exposure"], "-Infinity"), 422, ["film.exposure"]),
    case("1e999 is Infinity", scene_with(["camera", "vfov"], "1e999"), 422, ["camera.vfov"]),
    case("NaN raytree x", with_fields('"x": NaN, "y": 0'), 422, ["x"], url="/api/raytree"),
    case("NaN validate", with_fields('"other": NaN'), 422, ["other"], url="/api/validate"),
    # huge sizes: limits, numbers, nesting, bodies
    case("huge width", scene_with(["film", "width"], "1000000000"), 422, ["film.width"]),
    case("huge pixels", scene_with(["film"], '{"width": 512, "height": 450}'), 422, ["film.height"]),
    case("huge spp", scene_with(["sampler", "spp"], "1048576"), 422, ["sampler.spp"]),
    case("spp not a square", scene_with(["sampler", "spp"], "8"), 422, ["sampler.spp"]),
    case("huge depth", scene_with(["render", "max_depth"], "60"), 422, ["render.max_depth"]),
    case("huge light samples", scene_with(["render", "light_samples"], "100"), 422, ["render.light_samples"]),
    case("a 5000-digit integer", scene_with(["film", "width"], "9" * 5000), 400, [""]),
    case("deep nesting", b'{"scene": ' + b"[" * 40 + b"]" * 40 + b"}", 400, [""]),
    case("very deep nesting", b"[" * 50_000 + b"]" * 50_000, 400, [""]),
    case("too large", b'{"scene": {"name": "' + b"x" * 200_000 + b'"}}', 413, [""]),
    # paths that try to leave their folder
    case(
        "asset outside the folder",
        scene_with(["objects", 0], MESH_AT.format("../../etc/passwd")),
        422,
        ["objects[0].file"],
    ),  # fmt: skip
    case("absolute asset path", scene_with(["objects", 0], MESH_AT.format("/etc/passwd")), 422, ["objects[0].file"]),
    case("id traversal", None, 404, None, url="/api/jobs/..%2F..%2Fjobs.sqlite3"),
    case("id traversal image", None, 404, None, url="/api/jobs/..%2Fjobs.sqlite3/image"),
    case("id a quote", None, 404, ["id"], url="/api/jobs/x'%20OR%20'1'='1"),
    case("scene traversal", None, 404, None, url="/api/scenes/..%2F..%2Fpyproject"),
    case("scene traversal preview", None, 404, None, url="/api/scenes/..%2Fserver%2Fmain/preview.png"),
    case("static traversal", None, 404, None, url="/..%2Fpyproject.toml"),
    # unknown ids and routes, bad parameters
    case("unknown job", None, 404, ["id"], url=f"/api/jobs/{ID}"),
    case("unknown job image", None, 404, ["id"], url=f"/api/jobs/{ID}/image"),
    case("unknown job events", None, 404, ["id"], url=f"/api/jobs/{ID}/events"),
    case("cancel unknown job", None, 404, ["id"], url=f"/api/jobs/{ID}", method="DELETE"),
    case("list bad status", None, 422, ["status"], url="/api/jobs?status=finished"),
    case("list limit 0", None, 422, ["limit"], url="/api/jobs?limit=0"),
    case("wrong method", b"{}", 405, [""], method="PUT"),
    case("no such route", None, 404, [""], url="/api/nothing"),
]


@pytest.mark.parametrize("method,url,body,ctype,status,want", CORPUS)
def test_api_errors_corpus_gets_4xx_with_a_message(client, method, url, body, ctype, status, want):
    headers = {"content-type": ctype} if ctype else {}
    got = check_error(client.request(method, url, content=body, headers=headers), status)
    if want is not None:
        assert [e["path"] for e in got] == want, got


def test_api_errors_brackets_inside_strings_do_not_count_as_nesting(client):
    r = post_raw(client, "/api/validate", with_scene(json.dumps({**tiny_scene(), "name": "[" * 99})))
    assert r.status_code == 200
    assert r.json()["valid"] is True


def test_api_errors_json_depth_read_by_arrays_is_the_regex_s():
    """The request gate finds the nesting of a large body with numpy (in a thread, off the event loop): on JSON
    documents with escaped quotes and brackets in their strings, and on 20 000 random strings of brackets,
    quotes and backslashes, its depth is the one of stripping strings by regular expression, or it leaves
    that text to the regular expression."""
    import random

    from server.core.jsondepth import _depth_by_regex, _depth_of_arrays, json_depth

    rng = random.Random(7)

    def document(depth: int = 0):
        r = rng.random()
        if depth > 6 or r < 0.3:
            return rng.choice(['a\\"[', "\\\\", "]}", '"', 'x\\\\\\"{', 1, 2.5, None, True])
        if r < 0.65:
            return [document(depth + 1) for _ in range(rng.randint(0, 4))]
        return {rng.choice(["k", "[", '\\"', "z}"]): document(depth + 1) for _ in range(rng.randint(0, 4))}

    for _ in range(2000):
        text = json.dumps(document()).encode()
        assert _depth_of_arrays(text) == _depth_by_regex(text) == json_depth(text), text
    left = 0
    for _ in range(20_000):
        text = bytes(rng.choice(b'[]{}"\\ab,: ') for _ in range(rng.randint(0, 40)))
        depth = _depth_of_arrays(text)
        left += depth is None
        assert depth in (None, _depth_by_regex(text)) and json_depth(text) == _depth_by_regex(text), text
    assert 0 < left < 20_000


def test_api_errors_invalid_json_names_line_and_column(client):
    r = post_raw(client, "/api/jobs", b'{\n  "scene": {\n    "camera": }\n}')
    assert r.status_code == 422
    assert check_error(r)[0]["message"].startswith("invalid JSON at line 3, column 15")


@pytest.mark.parametrize(
    "ctype,message",
    [
        ("text/plain", "the Content-Type is 'text/plain', not JSON: expected 'Content-Type: application/json'"),
        (None, "the request has no Content-Type header: expected 'Content-Type: application/json'"),
        (JSON, "the body must be a JSON object {...}"),
    ],
    ids=["text/plain", "no content type", "json array"],
)
def test_api_errors_a_body_not_sent_as_json_names_its_content_type(client, ctype, message):
    """A JSON object sent as text/plain (or with no Content-Type) is told that the Content-Type is wrong, not
    that the body is not an object; a JSON array sent as JSON is told that it is not an object."""
    body = with_scene(SCENE) if ctype != JSON else b"[1, 2]"
    headers = {"content-type": ctype} if ctype else {}
    for url in ("/api/jobs", "/api/validate", "/api/grade"):
        assert check_error(client.post(url, content=body, headers=headers), 422) == [{"path": "", "message": message}]


@pytest.mark.parametrize(
    "url,body",
    [
        ("/api/jobs", b'{"scene": {"name": "caf\xe9"}}'),  # Latin-1's é
        ("/api/validate", b'{"scene": {"name": "caf\xe9"}, "pad": "' + b"x" * 70_000 + b'"}'),  # read in a checker
        ("/api/grade/students", b'{"files": ["caf\xe9.json"]}'),  # a route of FastAPI's own parser
    ],
    ids=["small scene", "large scene", "other route"],
)
def test_api_errors_a_body_that_is_not_utf8_names_its_first_bad_byte(client, url, body):
    """Not "a number too long, or nesting too deep": the body is not UTF-8, at this byte offset."""
    at = body.index(b"\xe9")
    (error,) = check_error(post_raw(client, url, body), 400)
    assert error == {
        "path": "",
        "message": f"the body is not UTF-8 text: byte 0xe9 at offset {at} (invalid continuation byte); "
        "JSON must be sent as UTF-8",
    }


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_api_errors_bad_scene_corpus_points_at_the_field(library_limits, name):
    """Errors raised inside the scene's model validators keep the offending field's own path."""
    client = library_limits
    text = (BAD_DIR / name).read_text()
    r = post_raw(client, "/api/jobs", with_scene(text))
    if name == "json_syntax.json":  # the whole request body is then invalid JSON
        assert paths(r) == [""] and "invalid JSON" in check_error(r)[0]["message"]
        return
    if name == "top_level_array.json":  # the body model wants an object
        assert paths(r) == ["scene"]
        return
    got = check_error(r, 422)
    assert [e["path"] for e in got] == [e["path"] for e in EXPECTED[name]], got
    for want, error in zip(EXPECTED[name], got, strict=True):
        assert want["message"] in error["message"]
    # the same errors from /api/validate, as a 200 report
    report = post_raw(client, "/api/validate", with_scene(text)).json()
    assert report["valid"] is False
    assert report["errors"] == got


def test_api_errors_too_many_primitives_points_at_objects(client):
    scene = tiny_scene()
    scene["objects"] += [{"type": "sphere", "center": [i, 0, -5], "radius": 0.1, "material": "red"} for i in range(30)]
    r = client.post("/api/jobs", json={"scene": scene})
    assert paths(r) == ["objects"] and "(limit max_primitives)" in r.json()["errors"][0]["message"]


def test_api_errors_streamed_body_over_the_limit_is_413(client):
    def chunks():
        yield b'{"scene": {"name": "'
        for _ in range(50):
            yield b"x" * 4096
        yield b'"}}'

    r = client.post("/api/jobs", content=chunks(), headers={"content-type": "application/json"})
    assert check_error(r, 413)[0]["message"].startswith("request body larger than 100000 bytes")


def test_api_errors_accepted_jobs_wait_without_a_worker(client):
    r = client.post("/api/jobs", json={"scene": tiny_scene()})
    assert r.status_code == 202
    assert r.json()["status"] == "queued"
    image = f"/api/jobs/{r.json()['id']}/image"
    assert paths(client.get(image, params={"format": "gif"})) == ["format"]
    assert paths(client.get(image, params={"pass": -1})) == ["pass"]
    assert check_error(client.get(image), 404)[0]["message"] == "no image yet: the job is queued"
    assert client.get("/api/health").json()["workers"] == []


def test_api_errors_openapi_documents_every_route(client):
    schema = client.get("/openapi.json").json()
    ops = {(path, method) for path, item in schema["paths"].items() for method in item}
    want = {
        ("/api/jobs", "post"),
        ("/api/jobs", "get"),
        ("/api/jobs/{job_id}", "get"),
        ("/api/jobs/{job_id}", "delete"),
        ("/api/jobs/{job_id}/image", "get"),
        ("/api/jobs/{job_id}/events", "get"),
        ("/api/raytree", "post"),
        ("/api/validate", "post"),
        ("/api/schema", "get"),
        ("/api/scenes", "get"),
        ("/api/scenes/{name}", "get"),
        ("/api/scenes/{name}/preview.png", "get"),
        ("/api/health", "get"),
    }
    assert want <= ops
    assert client.get("/docs").status_code == 200
    assert scene_dict("whitted")["camera"]  # the corpus builds on the example scenes


def test_api_errors_data_textures_that_are_not_images_are_refused_at_submit(client):
    """Five non-image data: textures: 422 at submit (not 202 and a failure in the worker), each at its path."""
    scene = tiny_scene()
    bad = [
        "data:image/png;base64,AAAA",
        "data:text/plain,hello",
        uri("image/png", b"GIF87a but not really"),
        uri("image/jpeg", b"\xff\xd8\xff"),
        obj_uri(1),
    ]
    for k, file in enumerate(bad):
        scene["materials"][f"bad{k}"] = {"texture": {"type": "image", "file": file}}
    scene["materials"]["good"] = {
        "texture": {"type": "image", "file": png_uri()},
        "bump": {"type": "image", "file": png_uri()},
    }
    want = [
        {"path": f"materials.bad{k}.texture.file", "message": "the data: URI is not a readable image (PNG or JPEG)"}
        for k in range(5)
    ]
    want[2]["message"] += ": it is a GIF image"  # told by its first bytes
    assert check_error(client.post("/api/jobs", json={"scene": scene}), 422) == want
    report = client.post("/api/validate", json={"scene": scene}).json()
    assert report == {"valid": False, "errors": want, "warnings": []}
    assert all(no_repr(e["message"]) for e in want)
    assert check_error(client.post("/api/raytree", json={"scene": scene, "x": 1, "y": 1}), 422) == want


def test_api_errors_mesh_triangles_count_against_the_primitive_limit(primitives_200):
    """A 3000-triangle data: OBJ against max_primitives 200: refused at submit, validate and raytree."""
    client = primitives_200
    scene = tiny_scene()
    scene["objects"].append({"type": "mesh", "file": obj_uri(30, 50), "material": {"kd": 0.5}})
    i = len(scene["objects"]) - 1
    (error,) = check_error(client.post("/api/jobs", json={"scene": scene}), 422)
    assert error["path"] == f"objects[{i}].file"  # counted when read, before it is built (issue #24)
    assert "makes 3000 triangles; must be at most 200 (limit max_primitives)" in error["message"]
    assert client.post("/api/validate", json={"scene": scene}).json()["errors"] == [error]
    assert check_error(client.post("/api/raytree", json={"scene": scene, "x": 1, "y": 1}), 422) == [error]
    scene["objects"][-1]["file"] = obj_uri(5, 5)  # 50 triangles
    assert client.post("/api/jobs", json={"scene": scene}).status_code == 202


def test_api_errors_missing_mesh_names_the_asset_folder_and_data_uris(client):
    scene = tiny_scene()
    scene["objects"].append({"type": "mesh", "file": "teapot.obj", "material": {"kd": 0.5}})
    report = client.post("/api/validate", json={"scene": scene}).json()
    (error,) = report["errors"]
    assert report["valid"] is False
    assert error["path"] == f"objects[{len(scene['objects']) - 1}].file"
    assert error["message"].startswith("asset file 'teapot.obj' not found in the asset folder ")
    assert "scenes/assets;" in error["message"]
    assert "as a data: URI" in error["message"]


@pytest.mark.parametrize(
    ("url", "extra", "example"),
    [
        ("/api/jobs", {}, '{"scene": {...}, "priority": 0}'),
        ("/api/validate", {}, '{"scene": {...}}'),
        ("/api/raytree", {"x": 1, "y": 2}, '{"scene": {...}, "x": 10, "y": 20}'),
    ],
)
def test_api_errors_bare_scene_gets_one_hint(client, url, extra, example):
    """A scene posted without {"scene": ...}: one error that says so, not one per key of the scene."""
    (error,) = check_error(client.post(url, json={**tiny_scene(), **extra}), 422)
    assert error == {
        "path": "",
        "message": f"the scene must be sent inside the request as {example}; this body has the scene's own "
        "fields (camera, objects, lights, ...) at its top level",
    }
    errors = check_error(client.post(url, json={"sceen": {}}), 422)  # no scene's field: the usual errors
    assert {"path": "scene", "message": "required field 'scene' is missing"} in errors
