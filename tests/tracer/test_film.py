"""The film (tracer/rendering/film.py): the reconstruction filters' sampling tables, sRGB encoding, EXR files.

The filters' importance sampling itself (offsets following |f|, negative weights) is checked through the
kernel in test_sampling.py; here, the tables it reads."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tracer.kernels.filters import FILTER_TABLE, filter_1d, filter_tables
from tracer.rendering.film import read_exr, srgb_encode, to_srgb8, write_exr

FILTERS = [("box", 0.5), ("box", 1.0), ("tent", 1.0), ("gaussian", 1.5), ("mitchell", 2.0)]


@pytest.mark.parametrize("kind, radius", FILTERS)
def test_film_filters_vanish_at_their_radius(kind, radius):
    x = np.linspace(-3, 3, 601)
    f = filter_1d(kind, radius, x)
    assert (f[np.abs(x) > radius + 1e-12] == 0).all()
    assert_allclose(f, f[::-1], atol=1e-15)  # even
    assert f[300] == f.max() > 0  # largest at the pixel centre


@pytest.mark.parametrize("kind, radius", FILTERS)
def test_film_filter_tables_invert_the_cdf_of_abs_f(kind, radius):
    icdf, sign, norm = filter_tables(kind, radius)
    assert icdf.shape == sign.shape == (FILTER_TABLE,)
    assert icdf.dtype == sign.dtype == np.float32
    assert icdf[0] == pytest.approx(-radius, abs=1e-3) and icdf[-1] == pytest.approx(radius, abs=1e-3)
    assert (np.diff(icdf) >= 0).all()
    # the share of table entries below x is the share of integral |f| below x (1e-3: the table's resolution)
    x = np.linspace(-radius, radius, 4001)
    a = np.abs(filter_1d(kind, radius, x))
    cdf = np.concatenate([[0], np.cumsum((a[1:] + a[:-1]) / 2)])
    for q in (0.1, 0.25, 0.5, 0.75, 0.9):
        below = np.searchsorted(icdf, np.interp(q, cdf / cdf[-1], x)) / FILTER_TABLE
        assert below == pytest.approx(q, abs=2e-3), (kind, q)
    # norm = (integral |f| / integral f)^2 per pixel sample: 1 unless the filter has negative lobes
    assert (sign < 0).any() == (kind == "mitchell")
    if kind == "mitchell":
        assert norm > 1.0
    else:
        assert norm == pytest.approx(1.0, abs=1e-12) and (sign == 1).all()


def test_film_srgb_encoding_known_values():
    """IEC 61966-2-1: linear below 0.0031308, the 2.4 power above; 0.5 linear is sRGB code 188."""
    assert_allclose(srgb_encode(np.array([0.0, 0.0031308, 1.0])), [0.0, 0.0031308 * 12.92, 1.0], atol=1e-7)
    assert to_srgb8(np.full((1, 1, 3), 0.5))[0, 0, 0] == 188
    assert to_srgb8(np.full((1, 1, 3), 0.25), exposure=1.0)[0, 0, 0] == 188  # one stop brighter
    assert to_srgb8(np.array([[[np.nan, np.inf, -1.0]]])).tolist() == [[[0, 255, 0]]]


def test_film_exr_keeps_the_linear_floats(tmp_path):
    image = np.random.default_rng(0).random((3, 5, 3), dtype=np.float32) * 100
    write_exr(tmp_path / "a.exr", image)
    assert np.array_equal(read_exr(tmp_path / "a.exr"), image)
