"""camera.instants: point-sampled time (N still frames averaged) against a continuous time per ray."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tests.support.scene import scene_dict, small
from tracer.kernels.compile import compile_scene
from tracer.rendering.progressive import Renderer, render
from tracer.rendering.raytree import ray_tree
from tracer.scene import SceneError, load_scene, validate_scene

N = 2  # instants
SPP = 4


def moving(spp: int = SPP, **camera) -> dict:
    return small(scene_dict("motion_blur"), 16, 12, sampler={"type": "random", "spp": spp}, camera=camera)


def instant(k: int, n: int = N, shutter=(0.0, 1.0)) -> float:
    return shutter[0] + (k + 0.5) * (shutter[1] - shutter[0]) / n


def test_instants_image_is_the_average_of_still_frames_at_those_instants():
    """Sample s of a pixel is taken at instant s mod N: the image is the mean over s of sample s rendered still
    (shutter closed to that one instant), which is N still frames of spp / N samples each, averaged."""
    scene, _ = load_scene(moving(instants=N))
    img = render(scene, threads=2).image
    stills = [compile_scene(load_scene(moving(shutter=[instant(k)] * 2))[0]) for k in range(N)]
    samples = []
    for s in range(SPP):
        r = Renderer(stills[s % N], threads=2)
        r.add_samples(s, s + 1)  # sample s alone, at the instant it is given
        samples.append(r.film.accum.numpy())  # its value (the box filter's weight is 1)
    assert_allclose(img, np.mean(samples, axis=0), rtol=1e-5, atol=1e-6)
    # each instant is used by spp / N samples: the frames at each instant, averaged
    frames = [np.mean(samples[k::N], axis=0) for k in range(N)]
    assert_allclose(img, np.mean(frames, axis=0), rtol=1e-5, atol=1e-6)
    # and it is not the continuous-time image (the ball moves)
    continuous = render(load_scene(moving())[0], threads=2).image
    assert not np.allclose(img, continuous, atol=1e-3)


def test_instants_give_each_sample_its_instant_and_are_deterministic():
    scene, _ = load_scene(moving(6, instants=3, shutter=[0.5, 2.0]))
    cs = compile_scene(scene)
    for s in range(6):
        assert ray_tree(cs, 5, 6, s)["time"] == pytest.approx(instant(s % 3, 3, (0.5, 2.0)), abs=1e-6)
    one, two = render(cs, threads=1), render(cs, threads=2)
    assert np.array_equal(one.image, two.image)
    # the continuous time of the same samples is drawn, not fixed
    times = {round(ray_tree(compile_scene(load_scene(moving())[0]), 5, 6, s)["time"], 6) for s in range(4)}
    assert len(times) == 4


def test_instants_are_validated_and_warned_about():
    with pytest.raises(SceneError) as err:
        load_scene(moving(instants=0))
    assert "camera.instants" in str(err.value)
    still = validate_scene(small(scene_dict("whitted"), 16, 12, camera={"instants": 4}))
    assert any(w["path"] == "camera.instants" and "nothing moves" in w["message"] for w in still["warnings"])
    uneven = validate_scene(moving(instants=3))
    assert any(w["path"] == "camera.instants" and "not used equally" in w["message"] for w in uneven["warnings"])
    assert not any(w["path"] == "camera.instants" for w in validate_scene(moving(instants=2))["warnings"])
