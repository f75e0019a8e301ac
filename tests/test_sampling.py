"""The RNG and the film samplers, through tiny kernels: uniformity (chi-square) and strata."""

import numpy as np
import warp as wp

import tracer.kinds  # noqa: F401  (initialise Warp)
from tracer.kinds import SamplerKind
from tracer.sampling import box_filter_offset, film_offset, rng_start


@wp.kernel
def k_draws(seed: int, n_dims: int, out: wp.array2d(dtype=float)):
    i = wp.tid()
    s = rng_start(seed, i % 1000, i / 1000)
    for j in range(n_dims):
        out[i, j] = wp.randf(s)


@wp.kernel
def k_film(sampler: int, spp: int, radius: float, out: wp.array2d(dtype=float)):
    i = wp.tid()  # i = pixel * spp + sample
    sample = i % spp
    s = rng_start(0, i / spp, sample)
    u1 = wp.randf(s)
    u2 = wp.randf(s)
    uv = box_filter_offset(film_offset(sampler, sample, spp, u1, u2), radius)
    out[i, 0] = uv[0]
    out[i, 1] = uv[1]


def chi_square_uniform(x: np.ndarray, bins: int) -> float:
    counts, _ = np.histogram(x, bins=bins, range=(0, 1))
    expected = len(x) / bins
    return float(((counts - expected) ** 2 / expected).sum())


def test_sampling_rng_uniform_and_independent():
    n = 200_000
    out = wp.zeros((n, 3), dtype=float)
    wp.launch(k_draws, dim=n, inputs=[0, 3, out])
    x = out.numpy()
    assert x.min() >= 0 and x.max() < 1
    # chi-square with 63 degrees of freedom: the 99.9% quantile is ~103.4
    for j in range(3):
        assert chi_square_uniform(x[:, j], 64) < 103.4
    # dimensions pairwise: 8x8 joint histogram, 63 dof
    h, _, _ = np.histogram2d(x[:, 0], x[:, 1], bins=8, range=[[0, 1], [0, 1]])
    e = n / 64
    assert ((h - e) ** 2 / e).sum() < 103.4
    # the same key gives the same numbers; another seed gives others
    again = wp.zeros((n, 3), dtype=float)
    wp.launch(k_draws, dim=n, inputs=[0, 3, again])
    assert np.array_equal(again.numpy(), x)
    other = wp.zeros((n, 3), dtype=float)
    wp.launch(k_draws, dim=n, inputs=[1, 3, other])
    assert np.abs(other.numpy() - x).mean() > 0.1


def film(sampler: SamplerKind, spp: int, pixels: int, radius: float = 0.5) -> np.ndarray:
    out = wp.zeros((pixels * spp, 2), dtype=float)
    wp.launch(k_film, dim=pixels * spp, inputs=[int(sampler), spp, radius, out])
    return out.numpy().reshape(pixels, spp, 2)


def test_sampling_center_and_grid_positions():
    assert np.array_equal(film(SamplerKind.CENTER, 1, 3), np.full((3, 1, 2), 0.5, np.float32))
    g = film(SamplerKind.GRID, 9, 2)
    cells = (np.arange(3) + 0.5) / 3
    expected = np.array([[cells[k % 3], cells[k // 3]] for k in range(9)], np.float32)
    np.testing.assert_allclose(g[0], expected, rtol=1e-6)
    assert np.array_equal(g[0], g[1])  # the grid does not depend on the pixel


def test_sampling_jittered_one_sample_per_stratum_and_uniform():
    j = film(SamplerKind.JITTERED, 16, 5000)
    cell = np.floor(j * 4).astype(int)
    k = np.arange(16)
    assert np.array_equal(cell[..., 0], np.broadcast_to(k % 4, (5000, 16)))
    assert np.array_equal(cell[..., 1], np.broadcast_to(k // 4, (5000, 16)))
    # within its cell each sample is uniform: chi-square of the fractional position, 63 dof
    frac = (j * 4) % 1
    assert chi_square_uniform(frac[..., 0].ravel(), 64) < 103.4
    assert chi_square_uniform(frac[..., 1].ravel(), 64) < 103.4


def test_sampling_random_uniform_over_the_pixel():
    r = film(SamplerKind.RANDOM, 4, 20000)
    assert chi_square_uniform(r[..., 0].ravel(), 64) < 103.4
    assert chi_square_uniform(r[..., 1].ravel(), 64) < 103.4


def test_sampling_box_filter_radius_spreads_samples():
    r = film(SamplerKind.RANDOM, 1, 20000, radius=1.0)
    assert r.min() < -0.45 and r.max() > 1.45 and r.min() >= -0.5 and r.max() <= 1.5
