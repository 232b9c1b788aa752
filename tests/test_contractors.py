"""Contractors never remove a feasible point (sampled truths) and do shrink boxes."""

from __future__ import annotations

import math

import numpy as np

from localization import contractors as C
from localization.chain import chain, relaxed_chain
from localization.interval import IV
from localization.odometry import motion

E = 0.33
N = 400


def _box_around(rng, v, lo_w, hi_w):
    """A random box containing each value of ``v`` (not centred on it)."""
    a = rng.uniform(lo_w, hi_w, np.shape(v))
    b = rng.uniform(lo_w, hi_w, np.shape(v))
    return IV.of(v - a, v + b)


def _truth_odometry(rng):
    s0 = np.stack([rng.uniform(-20, 20, N), rng.uniform(-20, 20, N), rng.uniform(-4, 4, N)])
    dsr = rng.uniform(-0.05, 0.15, N)
    dsl = rng.uniform(-0.05, 0.15, N)
    s1 = np.stack([motion(s0[:, k], (dsr[k], dsl[k]), E) for k in range(N)], axis=1)
    return s0, s1, dsr, dsl


def test_odometry_contractor_keeps_truth_and_shrinks():
    rng = np.random.default_rng(11)
    s0, s1, dsr, dsl = _truth_odometry(rng)
    x0, y0, t0 = (_box_around(rng, s0[i], 0.01, 0.3) for i in range(3))
    x1, y1, t1 = (_box_around(rng, s1[i], 0.5, 2.0) for i in range(3))
    r, l = _box_around(rng, dsr, 0.0, 0.002), _box_around(rng, dsl, 0.0, 0.002)
    e = IV.of(E)
    out = C.contract_odometry(x0, y0, t0, x1, y1, t1, r, l, e)
    truths = (s0[0], s0[1], s0[2], s1[0], s1[1], s1[2], dsr, dsl)
    for iv, t in zip(out, truths, strict=True):
        assert np.all(iv.contains(t))
    before = (x1.width() * y1.width()).sum()
    after = (out[3].width() * out[4].width()).sum()
    assert after < 0.2 * before  # the wide end box collapses onto the propagated one
    # Backward: a tight end box tightens a wide start box.
    out2 = C.contract_odometry(
        s0[0] + IV.of(-2.0, 2.0), y0, t0, IV.around(s1[0], 0.01), y1, t1, r, l, e
    )
    assert np.all(out2[0].contains(s0[0]))
    assert np.mean(out2[0].width()) < 0.5


def test_paper_form_of_eq2_is_an_option():
    rng = np.random.default_rng(12)
    s0 = np.array([1.0, 2.0, 0.3])
    s1 = motion(s0, (0.1, 0.09), E, kappa=1.0, chord=False)
    out = C.contract_odometry(
        *(IV.around(v, 0.01) for v in s0),
        *(IV.around(v, 1.0) for v in s1),
        IV.around(0.1, 1e-4),
        IV.around(0.09, 1e-4),
        IV.of(E),
        kappa=1.0,
        chord=False,
    )
    assert all(bool(iv.contains(v)) for iv, v in zip(out[:6], [*s0, *s1], strict=True))
    assert float(out[3].width()) < 0.1
    del rng


def test_gps_and_gyro_contractors():
    rng = np.random.default_rng(13)
    truth = rng.uniform(-10, 10, (N, 2))
    x, y = _box_around(rng, truth[:, 0], 0.1, 3), _box_around(rng, truth[:, 1], 0.1, 3)
    zx, zy = _box_around(rng, truth[:, 0], 0.1, 1), _box_around(rng, truth[:, 1], 0.1, 1)
    cx, cy = C.contract_position(x, y, zx, zy)
    assert np.all(cx.contains(truth[:, 0])) and np.all(cy.contains(truth[:, 1]))
    assert (cx.width() < x.width()).mean() > 0.5
    th = rng.uniform(-3, 3, N)
    box = _box_around(rng, th + 2 * math.pi, 0.01, 0.5)  # the box on another branch
    z = _box_around(rng, th, 0.01, 0.1)
    ct, _ = C.contract_heading(box, z)
    assert np.all(ct.contains(th + 2 * math.pi))
    assert np.all(ct.width() <= z.width() + 1e-12)


def test_range_bearing_contractor_keeps_truth_and_shrinks():
    rng = np.random.default_rng(14)
    pi_ = np.stack([rng.uniform(-20, 20, N), rng.uniform(-20, 20, N), rng.uniform(-3, 3, N)])
    pj = np.stack([rng.uniform(-20, 20, N), rng.uniform(-20, 20, N)])
    d = pj - pi_[:2]
    rho = np.hypot(*d)
    beta = np.arctan2(d[1], d[0]) - pi_[2]
    xi, yi = _box_around(rng, pi_[0], 0.5, 3), _box_around(rng, pi_[1], 0.5, 3)
    ti = _box_around(rng, pi_[2], 0.005, 0.02)
    xj, yj = _box_around(rng, pj[0], 0.05, 0.3), _box_around(rng, pj[1], 0.05, 0.3)
    r, b = _box_around(rng, rho, 0.0, 0.05), _box_around(rng, beta, 0.0, 0.01)
    out, _ = C.fixpoint(C.contract_range_bearing, [xi, yi, ti, xj, yj, r, b], tol=1e-3)
    for iv, t in zip(out, [pi_[0], pi_[1], pi_[2], pj[0], pj[1], rho, beta], strict=True):
        assert np.all(iv.contains(t))
    assert np.median(out[0].width() / xi.width()) < 0.5


def test_landmark_range_contractor():
    rng = np.random.default_rng(15)
    p = rng.uniform(-10, 10, (2, N))
    lm = rng.uniform(-10, 10, (2, N))
    rho = np.hypot(*(p - lm))
    x, y = _box_around(rng, p[0], 0.5, 4), _box_around(rng, p[1], 0.5, 4)
    r = _box_around(rng, rho, 0.0, 0.05)
    (cx, cy, cr), n = C.fixpoint(
        lambda a, b, c: C.contract_landmark_range(a, b, IV.of(lm[0]), IV.of(lm[1]), c), [x, y, r]
    )
    assert n >= 1
    assert np.all(cx.contains(p[0])) and np.all(cy.contains(p[1])) and np.all(cr.contains(rho))
    assert (cx.width() * cy.width()).sum() < (x.width() * y.width()).sum()


def test_inconsistent_constraint_gives_empty():
    x, y = IV.of(0.0, 1.0), IV.of(0.0, 1.0)
    cx, cy = C.contract_position(x, y, IV.of(5.0, 6.0), IV.of(0.0, 1.0))
    assert bool(cx.is_empty())
    (ox, *_), _ = C.fixpoint(
        lambda a, b, c: C.contract_landmark_range(a, b, IV.of(0.0), IV.of(0.0), c),
        [x, y, IV.of(10.0, 11.0)],
    )
    assert bool(ox.is_empty())


def test_fixpoint_stops_when_nothing_shrinks():
    calls = []

    def halve(a):
        calls.append(1)
        return (IV.of(a.lo, a.lo + 0.5 * (a.hi - a.lo)),)

    (out,), n = C.fixpoint(halve, [IV.of(0.0, 1.0)], tol=0.6, max_iter=10)
    assert n == 1 and len(calls) == 1  # shrank by 50% < 60%: stop
    (out,), n = C.fixpoint(halve, [IV.of(0.0, 1.0)], tol=0.4, max_iter=7)
    assert n == 7


def test_chain_matches_brute_force_and_keeps_truth():
    rng = np.random.default_rng(16)
    n = 40
    steps = rng.normal(0, 1, n - 1)
    v = np.concatenate([[0.0], np.cumsum(steps)])
    d = _box_around(rng, steps, 0.0, 0.05)
    m = _box_around(rng, v, 0.1, 2.0)
    out = chain(m, d)
    assert np.all(out.contains(v))
    # Brute force: intersect every measurement propagated to every step.
    for k in range(n):
        lo, hi = -np.inf, np.inf
        for j in range(n):
            if j <= k:
                lo = max(lo, m.lo[j] + d.lo[j:k].sum())
                hi = min(hi, m.hi[j] + d.hi[j:k].sum())
            else:
                lo = max(lo, m.lo[j] - d.hi[k:j].sum())
                hi = min(hi, m.hi[j] - d.lo[k:j].sum())
        assert abs(out.lo[k] - lo) < 1e-9 and abs(out.hi[k] - hi) < 1e-9
    assert out.width().mean() < m.width().mean()


def test_relaxed_chain_tolerates_outliers():
    rng = np.random.default_rng(17)
    n = 30
    steps = rng.normal(0, 0.1, n - 1)
    v = np.concatenate([[0.0], np.cumsum(steps)])
    d = IV.around(steps, 0.001)
    meas = v + rng.uniform(-0.9, 0.9, n)
    meas[[5, 20]] += 10.0  # two jumps far beyond the bound
    m = IV.around(meas, 1.0)
    valid = np.ones(n, bool)
    assert bool(np.any(chain(m, d).is_empty()))  # the plain intersection is empty
    out, consistent = relaxed_chain(m, valid, d, q=2)
    assert np.all(out.contains(v))
    assert set(np.flatnonzero(~consistent)) == {5, 20}
    out0, _ = relaxed_chain(m, valid, d, q=0)
    assert bool(np.any(out0.is_empty()))
