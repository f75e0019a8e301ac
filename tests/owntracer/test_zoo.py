"""The bug zoo: the student tracer's tree logs (zoo_tracer.py), each with one classic bug of the lecture, through
the service's feedback (tracer/grading/explain.py): it names the bug first, and finds nothing in the correct
tracer's trees."""

from __future__ import annotations

import pytest

from tests.owntracer.zoo_tracer import BUGS, bug_pixels, zoo_render, zoo_scene

SAMPLES = 12  # pixels tried per bug, spread over the pixels where it shows
# Besides its own `what`, what a bug may show first at some of its pixels: None where the change stays inside the
# feedback's tolerance (a highlight a little wider and very faint), and total internal reflection where n2 / n1
# bends a ray entering the glass ball at its rim beyond 90 degrees.
ALSO = {"specular_vector": {None}, "ior_inverted": {"total_internal_reflection"}}


@pytest.fixture(scope="module")
def explainer(compiled_kernels):
    from tracer.grading.explain import Explainer

    return Explainer(zoo_scene())


def spread(pixels: list, n: int = SAMPLES) -> list:
    """n of the pixels, evenly spaced in their (raster) order."""
    if len(pixels) <= n:
        return list(pixels)
    return [pixels[(2 * i + 1) * len(pixels) // (2 * n)] for i in range(n)]


def first_whats(explainer, bug: str | None, pixels: list) -> dict:
    """The first difference's `what` at each pixel (None: the tree matches) of the tracer with `bug`."""
    _, trees, picture = zoo_render(bug)
    out = {}
    for i in range(0, len(pixels), 64):  # a log holds 64 trees at most
        log = {"trees": [trees[p] for p in pixels[i : i + 64]]}
        for answer in explainer.compare(log, picture):
            assert answer["matches"] == (not answer["differences"])
            out[tuple(answer["pixel"])] = answer["differences"][0]["what"] if answer["differences"] else None
    return out


@pytest.mark.parametrize("bug", BUGS)
def test_zoo_names_each_bug_first(explainer, bug):
    whats = first_whats(explainer, bug, spread(bug_pixels(bug)))
    named = [p for p, what in whats.items() if what == BUGS[bug]]
    assert len(named) >= 3, f"{bug}: expected '{BUGS[bug]}' first at 3 of these pixels or more: {whats}"
    assert set(whats.values()) <= {BUGS[bug], *ALSO.get(bug, ())}, whats


def test_zoo_correct_tracer_matches_at_every_pixel(explainer):
    """Every pixel of the zoo scene, grazing rays too: the correct tracer's tree and picture match."""
    _, trees, _ = zoo_render(None)
    whats = first_whats(explainer, None, list(trees))
    assert len(whats) == len(trees)
    assert {p: w for p, w in whats.items() if w is not None} == {}
