"""The reconstruction filters of the film (box, tent, Gaussian, Mitchell) and the tables the kernels sample
pixel offsets from (filter importance sampling): plain numpy, filled into `SceneData` by compile.py."""

from __future__ import annotations

import math

import numpy as np

FILTER_TABLE = 4096  # entries of the inverse-CDF table


def filter_1d(kind: str, radius: float, x: np.ndarray) -> np.ndarray:
    """The separable reconstruction filters in 1D, x in pixels from the pixel centre."""
    ax = np.abs(x)
    if kind == "tent":
        return np.maximum(0.0, radius - ax)
    if kind == "gaussian":  # sigma = radius / 3, shifted to reach 0 at the radius (as pbrt)
        sigma = radius / 3
        return np.maximum(0.0, np.exp(-(x**2) / (2 * sigma**2)) - math.exp(-(radius**2) / (2 * sigma**2)))
    if kind == "mitchell":  # Mitchell & Netravali 1988, B = C = 1/3, stretched over the radius
        b = c = 1 / 3
        t = np.abs(2 * x / radius)
        near = (12 - 9 * b - 6 * c) * t**3 + (-18 + 12 * b + 6 * c) * t**2 + (6 - 2 * b)
        far = (-b - 6 * c) * t**3 + (6 * b + 30 * c) * t**2 + (-12 * b - 48 * c) * t + (8 * b + 24 * c)
        return np.where(t < 1, near, np.where(t < 2, far, 0.0)) / 6
    return np.where(ax <= radius, 1.0, 0.0)  # box


def filter_tables(kind: str, radius: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Filter importance sampling (Ernst et al. 2006): offsets drawn from |f| by inverse CDF, each
    sample weighted by sign(f) * (integral |f| / integral f) per dimension, so tiles stay independent."""
    x = np.linspace(-radius, radius, 8 * FILTER_TABLE + 1)
    f = filter_1d(kind, radius, x)
    a = np.abs(f)
    cdf = np.concatenate([[0.0], np.cumsum((a[1:] + a[:-1]) / 2)])
    cdf /= cdf[-1]
    u = np.linspace(0.0, 1.0, FILTER_TABLE)
    icdf = np.interp(u, cdf, x)
    sign = np.where(filter_1d(kind, radius, icdf) < 0, -1.0, 1.0)
    norm = (np.trapezoid(a, x) / np.trapezoid(f, x)) ** 2
    return icdf.astype(np.float32), sign.astype(np.float32), float(norm)
