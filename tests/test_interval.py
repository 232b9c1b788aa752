"""Guaranteed interval arithmetic: containment of exact results, outward rounding, empties."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from localization import interval as I
from localization.interval import IV

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
angles = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False)


def _iv(a: float, b: float) -> IV:
    return IV.of(min(a, b), max(a, b))


def _inside(iv: IV, exact) -> bool:
    lo, hi = float(iv.lo), float(iv.hi)
    return (lo == -math.inf or Fraction(lo) <= exact) and (hi == math.inf or exact <= Fraction(hi))


@settings(max_examples=150, deadline=None)
@given(finite, finite, finite, finite, st.floats(0, 1), st.floats(0, 1))
def test_arithmetic_contains_exact_results(a, b, c, d, s, t):
    x, y = _iv(a, b), _iv(c, d)
    # Points inside each interval, as exact rationals.
    px = Fraction(float(x.lo)) + (Fraction(float(x.hi)) - Fraction(float(x.lo))) * Fraction(s)
    py = Fraction(float(y.lo)) + (Fraction(float(y.hi)) - Fraction(float(y.lo))) * Fraction(t)
    assert _inside(x + y, px + py)
    assert _inside(x - y, px - py)
    assert _inside(x * y, px * py)
    assert _inside(I.sqr(x), px * px)
    if py != 0:
        q = x / y
        assert _inside(q, px / py)


@settings(max_examples=150, deadline=None)
@given(angles, angles, st.floats(0, 1))
def test_trig_contains_true_values(a, b, s):
    x = _iv(a, b)
    p = float(x.lo) + (float(x.hi) - float(x.lo)) * s
    p = min(max(p, float(x.lo)), float(x.hi))
    assert I.cos(x).contains(math.cos(p))
    assert I.sin(x).contains(math.sin(p))
    # Extremes are found: an interval over a full period is [-1, 1].
    if float(x.hi) - float(x.lo) >= 2 * math.pi:
        assert float(I.cos(x).lo) == -1.0 and float(I.cos(x).hi) == 1.0


@settings(max_examples=150, deadline=None)
@given(finite, finite, finite, finite, st.floats(0, 1), st.floats(0, 1))
def test_atan2_and_sqrt_contain_true_values(a, b, c, d, s, t):
    y, x = _iv(a, b), _iv(c, d)
    # a point of the box (the lerp can round outside it, e.g. -1 + (1 - 1e-110) == 0.0)
    py = min(max(float(y.lo) + (float(y.hi) - float(y.lo)) * s, float(y.lo)), float(y.hi))
    px = min(max(float(x.lo) + (float(x.hi) - float(x.lo)) * t, float(x.lo)), float(x.hi))
    ang = I.atan2(y, x)
    true = math.atan2(py, px)
    # Angles are real intervals: the true bearing lies in it modulo 2*pi.
    k = round((ang.mid() - true) / (2 * math.pi))
    assert ang.contains(true + 2 * math.pi * k) or ang.width() >= 2 * math.pi - 1e-9
    r = I.sqrt(I.sqr(x))
    assert r.contains(abs(px))


def test_outward_rounding_of_inexact_sums():
    s = IV.of(0.1) + IV.of(0.2)
    exact = Fraction(0.1) + Fraction(0.2)
    assert _inside(s, exact)
    assert float(s.lo) < 0.1 + 0.2 < float(s.hi)  # both bounds moved out by one ulp
    assert float(s.hi) == np.nextafter(0.1 + 0.2, np.inf)
    p = IV.of(1.0 / 3.0) * IV.of(3.0)
    assert _inside(p, Fraction(1.0 / 3.0) * 3)
    assert float(p.lo) < float(p.hi)


def test_empty_propagates_without_nan():
    e = IV.empty(())
    a = IV.of(1.0, 2.0)
    for r in (e + a, a - e, e * a, a / e, I.sqr(e), I.sqrt(e), I.cos(e), I.sin(e), I.atan2(e, a)):
        assert bool(r.is_empty())
        assert not np.isnan(r.lo) and not np.isnan(r.hi)
    assert bool((IV.of(0.0, 1.0) & IV.of(2.0, 3.0)).is_empty())
    assert bool(I.sqrt(IV.of(-3.0, -1.0)).is_empty())
    # Division by an interval containing 0 is unbounded, never an error.
    q = IV.of(1.0, 2.0) / IV.of(-1.0, 1.0)
    assert float(q.lo) == -math.inf and float(q.hi) == math.inf
    # 0 * inf does not produce NaN.
    z = IV.of(0.0, 1.0) * IV.entire(())
    assert float(z.lo) == -math.inf and float(z.hi) == math.inf


def test_vectorised_over_many_boxes():
    rng = np.random.default_rng(3)
    lo = rng.uniform(-5, 5, (200, 3))
    hi = lo + rng.uniform(0, 2, (200, 3))
    x = IV.of(lo, hi)
    pts = lo + (hi - lo) * rng.uniform(0, 1, (200, 3))
    c = I.cos(x * 2.0 + 1.0)
    assert c.shape == (200, 3)
    assert np.all(c.contains(np.cos(pts * 2.0 + 1.0)))
    hull = x | IV.of(lo + 10, hi + 10)
    assert np.all(hull.contains(pts)) and np.all(hull.contains(pts + 10))


@settings(max_examples=100, deadline=None)
@given(angles, st.floats(0.01, 3.0), st.floats(0, 1))
def test_backward_cos_sin_keep_feasible_points(a, w, s):
    x = IV.of(a, a + w)
    p = a + w * s
    z = IV.around(math.cos(p), 1e-3)
    assert I.bwd_cos(z, x).contains(p)
    z = IV.around(math.sin(p), 1e-3)
    assert I.bwd_sin(z, x).contains(p)


def test_backward_cos_contracts_on_a_branch():
    x = IV.of(0.1, 3.0)
    out = I.bwd_cos(IV.of(0.9, 1.0), x)
    assert float(out.hi) < math.acos(0.9) + 1e-9 and float(out.lo) == 0.1


def test_sinc_half_bounds():
    d = np.linspace(-0.5, 0.5, 101)
    c = I.sinc_half(IV.of(d))
    true = np.where(d == 0, 1.0, np.sin(d / 2) / np.where(d == 0, 1, d / 2))
    assert np.all(c.contains(true))


def test_align_angle():
    a = I.align_angle(IV.of(0.0, 0.1), 4 * math.pi + 0.05)
    assert abs(float(a.mid()) - (4 * math.pi + 0.05)) < 1e-9
