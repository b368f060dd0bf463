"""`classify.trig`'s branch-free sin, cos and atan2 against the C library's (numpy), in a numba
loop as the quadrature kernel calls them: within a few units in the last place."""
from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from ballsurvey.classify import trig


@numba.njit
def _sincos(x):
    s, c = np.empty_like(x), np.empty_like(x)
    for i in range(x.size):
        s[i], c[i] = trig.sincos(x[i])
    return s, c


@numba.njit
def _shift(m, d):
    s, c = np.empty_like(d), np.empty_like(d)
    sm, cm = math.sin(m), math.cos(m)
    for i in range(d.size):
        s[i], c[i] = trig.sincos_shift(sm, cm, d[i])
    return s, c


@numba.njit
def _atan2(y, x):
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = trig.atan2(y[i], x[i])
    return out


def _ulps(a, ref):
    return np.max(np.abs(a - ref) / np.spacing(np.maximum(np.abs(ref), 1e-300)))


@pytest.mark.parametrize("span", [math.pi / 4, math.pi / 2, 10.0, 1e3, 1e5])
def test_sincos_within_two_ulps_of_libm(span):
    x = np.random.default_rng(1).uniform(-span, span, 200_000)
    x[:6] = [0.0, -0.0, math.pi / 2, -math.pi / 2, math.pi / 4, span]
    s, c = _sincos(x)
    # where the result is near 0 the argument's own rounding dominates: compare absolutely there
    big_s, big_c = np.abs(np.sin(x)) > 1e-3, np.abs(np.cos(x)) > 1e-3
    assert _ulps(s[big_s], np.sin(x[big_s])) <= 2.0
    assert _ulps(c[big_c], np.cos(x[big_c])) <= 2.0
    assert np.max(np.abs(s - np.sin(x))) <= 4.5e-16 * max(1.0, span / 1e3)
    assert np.max(np.abs(c - np.cos(x))) <= 4.5e-16 * max(1.0, span / 1e3)


@pytest.mark.parametrize("m", [0.0873, 0.44, 1.2, 1.5707])
@pytest.mark.parametrize("h", [1e-6, 1e-3, 0.3])
def test_sincos_shift_is_the_angle_sum_to_rounding(m, h):
    d = np.random.default_rng(2).uniform(-h, h, 50_000)
    s, c = _shift(m, d)
    # reference in extended precision: sin and cos of m + d with d not rounded into the sum
    ml, dl = np.longdouble(m), d.astype(np.longdouble)
    es, ec = np.sin(ml + dl), np.cos(ml + dl)
    assert np.max(np.abs(s - es.astype(float))) <= 2.3e-16
    assert np.max(np.abs(c - ec.astype(float))) <= 2.3e-16
    if m + h < math.pi / 2:  # sin rises over the sweep: its values never step backwards
        s, _ = _shift(m, np.sort(d))
        assert np.all(np.diff(s) >= -2.3e-16)


def test_atan2_within_four_ulps_of_libm_in_every_octant():
    rng = np.random.default_rng(3)
    y = rng.normal(size=300_000) * rng.choice([1e-8, 1.0, 1e8], 300_000)
    x = rng.normal(size=300_000)
    a = _atan2(y, x)
    assert _ulps(a, np.arctan2(y, x)) <= 4.0
    axes = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, -1.0], [-1.0, 0.0], [1.0, 1.0], [-1.0, -1.0],
                     [0.0, 0.0]])
    got = _atan2(axes[:, 0].copy(), axes[:, 1].copy())
    assert np.allclose(got, np.arctan2(axes[:, 0], axes[:, 1]), rtol=0, atol=4.5e-16)
