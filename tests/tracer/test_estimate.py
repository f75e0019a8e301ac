"""The cost estimate (tracer/rendering/estimate.py) against the rays the renderer counts: it errs on the long side, and
counts a ray tree up to the bound the kernel keeps (issue 24: a glass ball in a box of mirrors, max_depth 64,
min_weight 0, was estimated at 0.068 s and never ended; the adaptive sampler with threshold 0 and max_level 8
at 32 x 32 was estimated at 0.12 s and took 4.2 s)."""

import json

import pytest

from tests.support.scene import EXAMPLES, ROOT, scene_dict, small
from tracer.integrators.adaptive import kept_points
from tracer.limits import Limits
from tracer.rendering import estimate
from tracer.rendering.progressive import render
from tracer.scene import load_scene

MIRROR_BOX = json.loads((ROOT / "tests" / "tracer" / "mirror_box.json").read_text())
# the adaptive sampler's rays are counted per grid point (the tests above), the others' per sample
UNIFORM = [p for p in EXAMPLES if json.loads(p.read_text()).get("sampler", {}).get("type") != "adaptive"]
INTERACTIVE_SECONDS = 20.0  # the service's default TRACER_INTERACTIVE_SECONDS: longer goes to the batch lane


def measured_rays_per_sample(scene) -> float:
    r = render(scene, threads=2)
    rays = {k: v for k, v in r.rays.items() if k not in ("total", "radiosity")}  # the solve is estimated apart
    return sum(rays.values()) / rays["eye"]


def test_estimate_counts_the_mirror_box_tree_at_its_bound(compiled_kernels):
    scene, _ = load_scene(small(MIRROR_BOX, 2, 2))
    assert estimate.tree_rays(scene) == Limits().max_tree_rays == 1024
    assert estimate.tree_rays(scene, 64) == 64
    assert estimate.rays_per_sample(scene) == 1024 * 2  # each tree ray and its one shadow ray
    measured = measured_rays_per_sample(scene)
    assert measured <= estimate.rays_per_sample(scene) <= 1.5 * measured
    # the same box at 256 x 256 and 16 samples is minutes of work, not an interactive job
    big, _ = load_scene(small(MIRROR_BOX, 256, 256, sampler={"type": "jittered", "spp": 16}))
    assert estimate.seconds(big, threads=2) > 5 * INTERACTIVE_SECONDS
    assert estimate.seconds(big, threads=2, limits=Limits(max_tree_rays=8)) < INTERACTIVE_SECONDS


def test_estimate_adaptive_threshold_0_splits_every_cell():
    """Threshold 0: every cell that is not flat is split down to max_level, so a pixel may cost all
    kept_points(max_level) grid points; the old count (5 + 12 per level) was 101 at level 8, against 131 585."""
    assert estimate.adaptive_points(0.0, 8) == kept_points(8) == 131_585
    assert estimate.adaptive_points(0.05, 3) == 5 + 12 * 3  # the example's threshold: the edges' cells only
    for level in range(9):
        assert estimate.adaptive_points(0.0, level) >= estimate.adaptive_points(0.001, level)
        assert estimate.adaptive_points(0.001, level) >= estimate.adaptive_points(0.05, level)


def test_estimate_adaptive_threshold_0_against_the_rays_traced(compiled_kernels):
    scene, _ = load_scene(small(scene_dict("antialias_adaptive"), 32, 24, sampler={"threshold": 0, "max_level": 4}))
    r = render(scene, threads=2)
    per_pixel = r.rays["eye"] / (32 * 24)
    assert per_pixel <= estimate.adaptive_points(0.0, 4) <= 2 * per_pixel


@pytest.mark.parametrize("path", UNIFORM, ids=[p.stem for p in UNIFORM])
def test_estimate_errs_long_within_3x_for_every_example(path, compiled_kernels):
    data = scene_dict(path.stem)
    if data.get("sampler", {}).get("type") in ("grid", "jittered", "random", "lowdiscrepancy"):
        data = small(data, 48, 36, sampler={"spp": 4})
    scene, _ = load_scene(small(data, 48, 36))
    measured = measured_rays_per_sample(scene)
    assert measured <= estimate.rays_per_sample(scene) <= 3 * measured
