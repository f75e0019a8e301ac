"""Intersection and shading helpers through tiny kernels, against values worked out by hand."""

import math

import numpy as np
import warp as wp
from numpy.testing import assert_allclose

import tracer.kernels.kinds  # noqa: F401  (initialise Warp)
from tracer.kernels.geometry import intersect_disk, intersect_parallelogram, intersect_plane, intersect_sphere
from tracer.kernels.materials import fresnel_dielectric, phong_terms, reflect, refract


@wp.kernel
def k_intersect(o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), out: wp.array2d(dtype=float)):
    i = wp.tid()
    out[i, 0] = intersect_sphere(o[i], d[i], wp.vec3(0.0, 0.0, 0.0), 1.0, 1.0e30)
    out[i, 1] = intersect_plane(o[i], d[i], wp.vec3(0.0, -1.0, 0.0), wp.vec3(0.0, 1.0, 0.0), 1.0e30)
    e1 = wp.vec3(2.0, 0.0, 0.0)
    e2 = wp.vec3(0.0, 2.0, 0.0)
    n = wp.cross(e1, e2)  # compile.py precomputes n and the edge coordinates' vectors for each quad
    w = n / wp.dot(n, n)
    corner = wp.vec3(-1.0, -1.0, -2.0)
    out[i, 2] = intersect_parallelogram(o[i], d[i], corner, wp.normalize(n), wp.cross(e2, w), wp.cross(w, e1), 1.0e30)
    out[i, 3] = intersect_disk(o[i], d[i], wp.vec3(0.0, 0.0, -3.0), wp.vec3(0.0, 0.0, 1.0), 0.5, 1.0e30)


def run_intersect(origins, dirs):
    o = wp.array(np.asarray(origins, np.float32), dtype=wp.vec3)
    d = wp.array(np.asarray(dirs, np.float32), dtype=wp.vec3)
    out = wp.zeros((len(origins), 4), dtype=float)
    wp.launch(k_intersect, dim=len(origins), inputs=[o, d, out])
    return out.numpy()


def test_geometry_intersections_exact():
    s2 = 1 / math.sqrt(2)
    t = run_intersect(
        [[0, 0, 5], [0, 0, 0], [0.9, 0, 5], [0, 5, 0], [0.6, 0, 5], [0, 0, 5]],
        [[0, 0, -1], [0, 0, -1], [0, 0, -1], [0, -s2, -s2], [0, 0, -1], [0, 0, 1]],
    )
    # from outside: sphere at 4, quad plane z=-2 at 7, disk z=-3 at 8; plane y=-1 parallel: miss
    assert_allclose(t[0], [4, -1, 7, 8], rtol=1e-6)
    # from the centre the sphere is hit from inside at t = 1
    assert_allclose(t[1], [1, -1, 2, 3], rtol=1e-6)
    # x = 0.9: sphere at 5 - sqrt(1 - 0.81); still inside the quad; outside the disk (r 0.5)
    assert_allclose(t[2], [5 - math.sqrt(0.19), -1, 7, -1], rtol=1e-5)
    # down at 45 degrees from (0,5,0): the plane y = -1 at t = 6 sqrt 2
    assert_allclose(t[3, 1], 6 * math.sqrt(2), rtol=1e-6)
    # x = 0.6: misses the disk of radius 0.5
    assert t[4, 3] == -1
    # looking away from everything
    assert_allclose(t[5], [-1, -1, -1, -1])


@wp.kernel
def k_optics(cos_i: wp.array(dtype=float), eta: wp.array(dtype=float), out: wp.array2d(dtype=float)):
    i = wp.tid()
    c = cos_i[i]
    d = wp.vec3(wp.sqrt(1.0 - c * c), -c, 0.0)
    n = wp.vec3(0.0, 1.0, 0.0)
    t, ok = refract(d, n, eta[i])
    r = reflect(d, n)
    out[i, 0] = fresnel_dielectric(c, eta[i])
    out[i, 1] = float(ok)
    out[i, 2] = t[0]
    out[i, 3] = t[1]
    out[i, 4] = r[1]


def run_optics(cos_i, eta):
    out = wp.zeros((len(cos_i), 5), dtype=float)
    wp.launch(k_optics, dim=len(cos_i), inputs=[wp.array(cos_i, dtype=float), wp.array(eta, dtype=float), out])
    return out.numpy()


def test_materials_fresnel_and_snell():
    brewster = math.atan(1.5)
    theta_c = math.asin(1 / 1.5)
    cos = [1.0, math.cos(brewster), math.cos(math.radians(60)), math.cos(theta_c + 0.05), 0.0]
    eta = [1 / 1.5, 1 / 1.5, 1 / 1.5, 1.5, 1 / 1.5]
    r = run_optics(cos, eta)
    # normal incidence: ((n1 - n2) / (n1 + n2))^2 = 0.04, straight through
    assert_allclose(r[0, 0], 0.04, rtol=1e-5)
    assert_allclose(r[0, 2:4], [0, -1], atol=1e-6)
    # Brewster's angle: rp = 0, so R = rs^2 / 2 with rs = cos(2 theta_B) ... = (n^2-1)^2/(n^2+1)^2 / 2
    n2 = 1.5**2
    assert_allclose(r[1, 0], ((n2 - 1) / (n2 + 1)) ** 2 / 2, rtol=1e-4)
    # Snell at 60 degrees: sin(theta_t) = sin 60 / 1.5
    assert_allclose(r[2, 2], math.sin(math.radians(60)) / 1.5, rtol=1e-5)
    assert r[2, 4] > 0  # the mirror direction leaves the surface
    # inside glass beyond the critical angle: total internal reflection, R = 1
    assert r[3, 1] == 0
    assert r[3, 0] == 1.0
    # grazing incidence: everything is reflected
    assert_allclose(r[4, 0], 1.0, atol=1e-6)


@wp.kernel
def k_phong(l: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), out: wp.array2d(dtype=float)):
    i = wp.tid()
    dterm, sterm = phong_terms(wp.vec3(0.5), wp.vec3(0.25), 10.0, wp.vec3(0.0, 1.0, 0.0), l[i], v[i])
    out[i, 0] = dterm[0]
    out[i, 1] = sterm[0]


def test_materials_phong_brdf_normalised():
    s2 = 1 / math.sqrt(2)
    l = np.array([[0, 1, 0], [s2, s2, 0], [s2, s2, 0], [0, -1, 0]], np.float32)
    v = np.array([[0, 1, 0], [-s2, s2, 0], [0, 1, 0], [0, 1, 0]], np.float32)
    out = wp.zeros((4, 2), dtype=float)
    wp.launch(k_phong, dim=4, inputs=[wp.array(l, dtype=wp.vec3), wp.array(v, dtype=wp.vec3), out])
    r = out.numpy()
    # light and eye along the normal: kd/pi, ks (n+2)/(2 pi)
    assert_allclose(r[0], [0.5 / math.pi, 0.25 * 12 / (2 * math.pi)], rtol=1e-5)
    # 45 degree light, eye in the mirror direction: cos(theta) = 1/sqrt 2, cos(alpha) = 1
    assert_allclose(r[1], [0.5 / math.pi * s2, 0.25 * 12 / (2 * math.pi) * s2], rtol=1e-5)
    # eye along the normal: alpha = 45 degrees
    assert_allclose(r[2, 1], 0.25 * 12 / (2 * math.pi) * s2**10 * s2, rtol=1e-4)
    # light below the surface contributes nothing
    assert_allclose(r[3], [0, 0])
