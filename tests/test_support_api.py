"""The API tests' helpers (tests/support/api.py): Server-Sent Events parsed, the small scenes valid."""

from __future__ import annotations

from tests.support.api import long_scene, parse_sse, tiny_scene


def test_api_support_parse_sse_events():
    lines = ["retry: 1000", "", ": keep-alive", "", "event: progress", 'data: {"a": 1}', "", 'data: {"b": 2}', ""]
    assert list(parse_sse(lines)) == [("progress", {"a": 1}), ("message", {"b": 2})]


def test_api_support_scenes_are_valid():
    from tracer.scene import load_scene

    assert load_scene(tiny_scene())[0].film.width == 16
    assert load_scene(long_scene())[0].sampler.spp == 1024
