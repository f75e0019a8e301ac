"""The RNG and the film samplers, through tiny kernels: uniformity (chi-square) and strata."""

import numpy as np
import warp as wp

from tracer.kernels.compile import compile_scene
from tracer.kernels.kinds import SamplerKind
from tracer.kernels.sampling import film_offset, film_uniforms, filter_offset, pixel_key, rng_start, sample_2d
from tracer.kernels.structs import SceneData
from tracer.scene import load_scene


@wp.kernel
def k_draws(seed: int, n_dims: int, out: wp.array2d(dtype=float)):
    i = wp.tid()
    s = rng_start(seed, i % 1000, i / 1000)
    for j in range(n_dims):
        out[i, j] = wp.randf(s)


@wp.kernel
def k_film(scene: SceneData, sampler: int, spp: int, out: wp.array2d(dtype=float)):
    i = wp.tid()  # i = pixel * spp + sample
    sample = i % spp
    u1, u2, s = film_uniforms(sampler, pixel_key(0, i / spp), sample, rng_start(0, i / spp, sample))
    uv, weight = filter_offset(scene, film_offset(sampler, sample, spp, u1, u2))
    out[i, 0] = uv[0]
    out[i, 1] = uv[1]
    out[i, 2] = weight


def film_scene(filter_type: str = "box", radius: float | None = None):
    flt = {"type": filter_type} if radius is None else {"type": filter_type, "radius": radius}
    scene, _ = load_scene({"camera": {"lookfrom": [0, 0, 1], "lookat": [0, 0, 0]}, "film": {"filter": flt}})
    return compile_scene(scene)


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


def film(sampler: SamplerKind, spp: int, pixels: int, filter_type: str = "box", radius=None, weights=False):
    cs = film_scene(filter_type, radius)
    out = wp.zeros((pixels * spp, 3), dtype=float)
    wp.launch(k_film, dim=pixels * spp, inputs=[cs.data, int(sampler), spp, out])
    r = out.numpy().reshape(pixels, spp, 3)
    return r if weights else r[..., :2]


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


def test_sampling_lowdiscrepancy_first_samples_are_nets():
    """The lowdiscrepancy sampler: any first 2^k samples of a pixel put one point in each cell of every
    2^a x 2^b grid with a + b = k (a (0, k, 2)-net: Owen-scrambled Sobol points), also as the first
    samples of a larger spp (a progressive pass); uniform over the pixel across pixels; and each pixel's
    points differ."""
    for spp in (4, 16, 64):
        pts = film(SamplerKind.LOWDISCREPANCY, spp, 2000)
        for k in range(1, spp.bit_length()):
            first = pts[:, : 1 << k]
            for a in range(k + 1):
                cell = np.floor(first[..., 0] * (1 << a)).astype(int) * (1 << (k - a))
                cell += np.floor(first[..., 1] * (1 << (k - a))).astype(int)
                assert (np.sort(cell, axis=1) == np.arange(1 << k)).all(), (spp, k, a)
    ld = film(SamplerKind.LOWDISCREPANCY, 16, 4000)
    assert chi_square_uniform(ld[..., 0].ravel(), 64) < 103.4
    assert chi_square_uniform(ld[..., 1].ravel(), 64) < 103.4
    assert np.abs(ld[1] - ld[0]).mean() > 0.1


def test_sampling_lowdiscrepancy_less_error_than_random_and_jittered():
    """The fraction of a pixel under an edge (x + 0.7 y < 0.8) from its samples: the lowdiscrepancy
    sampler's error is under half the random sampler's at 8, 16 and 32 samples, under 0.6x at 10 (no
    power of two), and no larger than the jittered grid's at 16."""
    area = 0.8 - 0.7 / 2  # the line crosses the square from side to side

    def error(pts: np.ndarray) -> float:
        under = (pts[..., 0] + 0.7 * pts[..., 1] < 0.8).mean(axis=1)
        return float(np.sqrt(((under - area) ** 2).mean()))

    rnd = film(SamplerKind.RANDOM, 32, 4000)
    for n in (8, 16, 32):
        assert error(film(SamplerKind.LOWDISCREPANCY, n, 4000)) < 0.5 * error(rnd[:, :n]), n
    assert error(film(SamplerKind.LOWDISCREPANCY, 10, 4000)) < 0.6 * error(rnd[:, :10])
    assert error(film(SamplerKind.LOWDISCREPANCY, 16, 4000)) <= error(film(SamplerKind.JITTERED, 16, 4000))


def test_sampling_box_filter_radius_spreads_samples():
    r = film(SamplerKind.RANDOM, 1, 20000, radius=1.0)
    assert r.min() < -0.45 and r.max() > 1.45 and r.min() >= -0.5 and r.max() <= 1.5


def test_sampling_filters_importance_sampled():
    """Offsets follow |f| (chi-square against the filter's own histogram); Mitchell's negative lobes
    come back as negative weights, and the weights average to 1 (the filter integrates to 1)."""
    from tracer.kernels.filters import filter_1d

    for kind, radius in (("tent", 1.0), ("gaussian", 1.5), ("mitchell", 2.0)):
        r = film(SamplerKind.RANDOM, 1, 100_000, kind, weights=True)[:, 0]
        x = r[:, 0] - 0.5
        assert np.abs(x).max() <= radius + 1e-5
        edges = np.linspace(-radius, radius, 33)
        fine = np.linspace(-radius, radius, 3201)
        dens = np.abs(filter_1d(kind, radius, fine))
        cdf = np.concatenate([[0], np.cumsum((dens[1:] + dens[:-1]) / 2)])
        expected = np.diff(np.interp(edges, fine, cdf / cdf[-1])) * len(x)
        counts, _ = np.histogram(x, bins=edges)
        keep = expected > 5
        chi2 = (((counts - expected) ** 2 / expected)[keep]).sum()
        assert chi2 < 70, (kind, chi2)  # ~31 dof: the 99.9% quantile is ~61.1 (a little slack for the table)
        w = r[:, 2]
        assert abs(w.mean() - 1) < 0.02, (kind, w.mean())
        assert (w < 0).any() == (kind == "mitchell")


@wp.kernel
def k_r2(key: wp.uint32, out: wp.array2d(dtype=float)):
    i = wp.tid()
    u = sample_2d(key, 7, i)
    out[i, 0] = u[0]
    out[i, 1] = u[1]


def test_sampling_r2_low_discrepancy_points():
    """Roberts' R2 points, shifted: uniform, and far more even than random ones (every one of 16x16
    cells gets 4 of the first 1024 points, give or take 2)."""
    out = wp.zeros((1024, 2), dtype=float)
    wp.launch(k_r2, dim=1024, inputs=[wp.uint32(12345), out])
    r = out.numpy()
    assert r.min() >= 0 and r.max() < 1
    h, _, _ = np.histogram2d(r[:, 0], r[:, 1], bins=16, range=[[0, 1], [0, 1]])
    assert h.min() >= 2 and h.max() <= 6
    other = wp.zeros((1024, 2), dtype=float)
    wp.launch(k_r2, dim=1024, inputs=[wp.uint32(54321), other])
    assert np.abs(other.numpy() - r).mean() > 0.1  # another pixel, another shift


@wp.kernel
def k_two_dims(keys: wp.array(dtype=wp.uint32), out: wp.array2d(dtype=float)):
    k, i = wp.tid()
    a = sample_2d(keys[k], 3, i)
    b = sample_2d(keys[k], 1027, i)  # the next bounce's dimension of the same pixel
    out[k, i] = wp.where(a[0] < b[0], 1.0, 0.0) + wp.where(a[1] < b[1], 2.0, 0.0)


def test_sampling_dimensions_independent_within_a_pixel():
    """Two dimension pairs of one pixel are independent of each other, not the same points shifted:
    with only a shift between them, whether a < b would be the same for most samples of a pixel (its
    share is the shift), and a path's bounces would be correlated, its error not falling with more
    samples. Per pixel, a < b holds for half of 4096 samples, in each coordinate."""
    keys = wp.array(np.array([k * 2654435761 % 2**32 for k in range(1, 9)], dtype=np.uint32), dtype=wp.uint32)
    out = wp.zeros((8, 4096), dtype=float)
    wp.launch(k_two_dims, dim=(8, 4096), inputs=[keys, out])
    r = out.numpy().astype(int)
    for bit in (1, 2):
        share = ((r & bit) != 0).mean(axis=1)
        assert np.all(np.abs(share - 0.5) < 0.05), share
