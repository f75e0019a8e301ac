"""Texts a user reads say what the files they describe hold."""

from __future__ import annotations

import re

import pytest

from tests.support.scene import ROOT, scene_dict

# (example, a phrase of its description with {} where a number stands, the JSON path of that number)
QUOTED = [
    ("depth_of_field", "A thin lens of radius {}", "camera.lens_radius"),
    ("depth_of_field", "focused at {} units", "camera.focus_distance"),
    ("fog", "fog of density {} per unit", "fog.density"),
    ("antialias_adaptive", "more than the threshold ({})", "sampler.threshold"),
    ("antialias_adaptive", "down to {} levels", "sampler.max_level"),
    ("antialias_grid", "{} rays per pixel", "sampler.spp"),
    ("antialias_jittered", "{} rays per pixel", "sampler.spp"),
    ("soft_shadows", "render.light_samples = {} stratified", "render.light_samples"),
    ("cornell_whitted_area", "{} stratified shadow rays", "render.light_samples"),
    ("cornell_radiosity", "patches of {} units", "render.radiosity.patch_size"),
    ("phong", "(max_depth {})", "render.max_depth"),
    ("whitted_depth1", "(max_depth {})", "render.max_depth"),
    ("whitted_depth2", "(max_depth {})", "render.max_depth"),
    ("whitted_depth3", "(max_depth {})", "render.max_depth"),
]


def _at(data: dict, path: str):
    for key in path.split("."):
        data = data[key]
    return data


@pytest.mark.parametrize(("name", "phrase", "path"), QUOTED, ids=[f"{n}:{p}" for n, _, p in QUOTED])
def test_texts_example_descriptions_quote_their_own_numbers(name, phrase, path):
    scene = scene_dict(name)
    pattern = re.escape(phrase).replace(r"\{\}", r"([-+]?\d+(?:\.\d+)?)")
    found = re.search(pattern, scene["description"])
    assert found, f"{name}.json's description no longer says {phrase!r}"
    assert float(found[1]) == pytest.approx(_at(scene, path)), f"{name}.json: the description says {found[0]!r}"


def test_texts_example_descriptions_point_to_the_page_not_the_command_line():
    """The examples' descriptions are read on the page's cards: for the rays-per-pixel picture they name the page's
    own button (the viewer's and each lesson panel's "Rays / pixel"), not a command line flag."""
    text = scene_dict("antialias_adaptive")["description"]
    assert "--aovs" not in text and "python -m" not in text, text
    assert "Rays / pixel" in text, text
    web = ROOT / "web" / "js"
    assert '["rays", "Rays / pixel"]' in (web / "viewer.js").read_text()
    assert re.search(r'"Rays / pixel",?\s*\)', (web / "lessons.js").read_text())  # a call's last argument
