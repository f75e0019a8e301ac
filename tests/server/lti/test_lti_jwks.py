"""The platforms' key sets, cached: fetched when not cached, fetched again once for an unknown kid, never in a
loop of forged kids; errors are LaunchError("jwks")."""

from __future__ import annotations

import pytest

from server.lti.launch import JwksCache, LaunchError, fetch_jwks
from tests.support.lti_platform import new_key


class Fetcher:
    def __init__(self, *keys):
        self.keys, self.calls = list(keys), []

    def __call__(self, url: str) -> dict:
        self.calls.append(url)
        return {"keys": [k.as_dict(private=False) for k in self.keys]}


class Clock:
    def __init__(self, now: float = 1000.0):
        self.now = now

    def __call__(self) -> float:
        return self.now


def test_lti_jwks_fetched_once_then_cached():
    a = new_key()
    fetch, clock = Fetcher(a), Clock()
    cache = JwksCache(fetch, min_interval=60, clock=clock)
    assert [k.kid for k in cache.key_set("https://lms/jwks", a.kid)] == [a.kid]
    cache.key_set("https://lms/jwks", a.kid)
    assert fetch.calls == ["https://lms/jwks"]


def test_lti_jwks_unknown_kid_refetched_once_per_interval():
    a, b = new_key(), new_key()
    fetch, clock = Fetcher(a), Clock()
    cache = JwksCache(fetch, min_interval=60, clock=clock)
    cache.key_set("u", a.kid)
    clock.now += 61
    with pytest.raises(LaunchError) as e:
        cache.key_set("u", "forged")
    assert e.value.check == "kid"
    assert len(fetch.calls) == 2  # fetched again, once
    for _ in range(5):  # forged kids within the interval: no more fetches
        with pytest.raises(LaunchError):
            cache.key_set("u", "forged-again")
    assert len(fetch.calls) == 2
    fetch.keys = [a, b]  # the platform rotates
    clock.now += 61
    assert b.kid in {k.kid for k in cache.key_set("u", b.kid)} and len(fetch.calls) == 3
    assert cache.key_set("u", a.kid) and len(fetch.calls) == 3


def test_lti_jwks_bad_answers_are_jwks_errors():
    for bad in ({"nokeys": []}, {"keys": []}, {"keys": [{"kty": "RSA", "kid": "x"}]}, ["not", "a", "dict"]):
        with pytest.raises(LaunchError) as e:
            JwksCache(lambda url, bad=bad: bad).key_set("u", "x")
        assert e.value.check == "jwks", bad


def test_lti_jwks_default_fetch_says_why_it_failed():
    with pytest.raises(LaunchError) as e:
        fetch_jwks("http://127.0.0.1:9/jwks")  # nothing listens on the discard port
    assert e.value.check == "jwks"
    assert "could not be fetched" in e.value.message


def test_lti_jwks_default_fetch_is_bounded_and_checks_the_answer():
    from fastapi import FastAPI
    from fastapi.responses import JSONResponse, Response

    from tests.support.lti_platform import LoopbackServer

    key = new_key()
    app = FastAPI()
    app.get("/good")(lambda: {"keys": [key.as_dict(private=False)]})
    app.get("/big")(lambda: {"keys": [], "padding": "x" * 70_000})
    app.get("/error")(lambda: JSONResponse({"error": "no"}, status_code=500))
    app.get("/text")(lambda: Response("not json", media_type="text/plain"))
    with LoopbackServer(app) as server:
        assert [k["kid"] for k in fetch_jwks(server.url + "/good")["keys"]] == [key.kid]
        for path, words in (("/big", "too large"), ("/error", "HTTP 500"), ("/text", "not JSON")):
            with pytest.raises(LaunchError) as e:
                fetch_jwks(server.url + path)
            assert e.value.check == "jwks" and words in e.value.message, e.value.message
