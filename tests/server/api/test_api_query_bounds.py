"""Every numeric query parameter of every route is bounded: huge, negative and non-finite values get a
4xx naming the parameter, never a 500, and the keep-alive connection they came on still serves the next
request (a 500 from an OverflowError used to drop it).

The routes and their parameters are read from the app's own OpenAPI schema, so a parameter added later
is walked too. Requests go to `python -m server` on loopback over one http.client connection."""

from __future__ import annotations

import http.client

import pytest

from tests.support.api import Server, submit, tiny_scene

HUGE = ["9223372036854775808", "-9223372036854775809", "1" + "0" * 40, "-1" + "0" * 40]
NON_FINITE = ["1e400", "-1e400", "nan", "inf"]


def _types(schema: dict) -> set[str]:
    """The JSON types a parameter's schema allows (through anyOf: optional parameters)."""
    found = {schema["type"]} if "type" in schema else set()
    for sub in schema.get("anyOf", []) + schema.get("oneOf", []):
        found |= _types(sub)
    return found


def numeric_query_parameters(openapi: dict) -> list[tuple[str, str, str, str]]:
    """(method, path, parameter, type) for every integer or number query parameter of every route."""
    out = []
    for path, ops in openapi["paths"].items():
        for method, op in ops.items():
            for param in op.get("parameters", []):
                kinds = _types(param.get("schema", {})) & {"integer", "number"}
                if param["in"] == "query" and kinds:
                    out.append((method.upper(), path, param["name"], "number" if "number" in kinds else "integer"))
    return out


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with Server(tmp_path_factory.mktemp("query") / "data", workers=0) as s:
        yield s


def test_query_bounds_every_numeric_parameter_gets_a_4xx_on_one_connection(server):
    openapi = server.client.get("/openapi.json").json()
    params = numeric_query_parameters(openapi)
    assert ("GET", "/api/jobs", "offset", "integer") in params
    assert ("GET", "/api/jobs", "limit", "integer") in params
    job_id = submit(server.client, tiny_scene())["id"]  # no workers: it stays queued, so job routes find it
    headers = {k: v for k, v in server.client.headers.items() if k.lower() not in ("accept-encoding", "connection")}
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    try:
        conn.connect()
        sock = conn.sock
        for method, path, name, kind in params:
            url = path.replace("{job_id}", job_id)
            for k in ("name", "run_id", "student", "file", "fmt"):
                url = url.replace("{" + k + "}", "x")
            for value in HUGE + (NON_FINITE if kind == "number" else ["1.5", "x"]):
                conn.request(method, f"{url}?{name}={value}", headers=headers)
                r = conn.getresponse()
                body = r.read().decode()
                where = f"{method} {url}?{name}={value}"
                assert 400 <= r.status < 500, f"{where}: {r.status} {body}"
                assert not r.will_close and conn.sock is sock, f"{where}: the connection was closed"
                if r.status == 422:
                    assert f'"path":"{name}"' in body, f"{where}: {body}"
        conn.request("GET", "/api/health", headers=headers)
        r = conn.getresponse()
        assert r.status == 200 and r.read() and conn.sock is sock
    finally:
        conn.close()


def test_query_bounds_offset_past_sqlite_integers_is_named(server):
    """The issue's request: 2**63 used to reach SQLite and overflow (500)."""
    r = server.client.get("/api/jobs", params={"offset": str(2**63)})
    assert r.status_code == 422, r.text
    [error] = r.json()["errors"]
    assert error["path"] == "offset"
    assert "1000000000" in error["message"]
    assert "query parameter" in error["message"]
    r = server.client.get("/api/jobs", params={"offset": "1000000000", "limit": "1000"})
    assert r.status_code == 200
    assert r.json()["jobs"] == []
