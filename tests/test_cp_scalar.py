"""The scalar fast path of the cooperative contraction (localization.cp_scalar) against
the array path it mirrors (localization.contractors / polar / interval_arith): same
bounds up to libm's last bit, every sampled feasible point kept, and the paper scenario
(cooperative CP, uniform errors) giving the same boxes either way."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import localization.cp_scalar as cps
import localization.interval_scalar as isc
from fakes.world.paper_scenario import simulate
from hilnav.fleet.paper import PaperRobot
from localization.contractors import contract_range_bearing
from localization.cp_window import SlidingWindowCP
from localization.interval import IV, bwd_mul, bwd_sqr, cos, meet_angle, sin, sqr
from localization.interval_arith import _div
from localization.interval_trig import bearing

SEEDED = settings(max_examples=300, derandomize=True, deadline=None, database=None)
# math.cos/sin/atan2/tan may differ from numpy's by an ulp of a value <= a few units,
# which the margins (1e-14) dwarf; every other operation is bit-identical.
TOL = 1e-13

bound = st.floats(-20.0, 20.0, allow_nan=False)
width = st.floats(0.0, 5.0, allow_nan=False)


def _iv(lo: float, w: float) -> tuple[float, float]:
    return (lo, lo + w)


def _same(a: tuple[float, float], b: IV, tol: float = 0.0) -> bool:
    lo, hi = float(b.lo), float(b.hi)
    if not lo <= hi:
        return not a[0] <= a[1]
    return all(u == v or abs(u - v) <= tol * (1 + abs(v)) for u, v in ((a[0], lo), (a[1], hi)))


def _IV(a: tuple[float, float]) -> IV:
    return IV.of(a[0], a[1])


@SEEDED
@given(bound, width, bound, width, bound, width)
def test_ops_match_the_array_ops(al, aw, bl, bw, cl, cw):
    a, b, c = _iv(al, aw), _iv(bl, bw), _iv(cl, cw)
    A, B, C = _IV(a), _IV(b), _IV(c)
    assert _same(isc.add(a, b), A + B)
    assert _same(isc.sub(a, b), A - B)
    assert _same(isc.mul(a, b), A * B)
    assert _same(isc.div(a, b), _div(A, B))
    assert _same(isc.sqr(a), sqr(A))
    assert _same(isc.bwd_sqr(a, b), bwd_sqr(A, B))
    assert _same(isc.bwd_mul(a, b, c), bwd_mul(A, B, C))
    assert _same(isc.cos(a), cos(A), TOL)
    assert _same(isc.sin(a), sin(A), TOL)
    assert _same(isc.bearing(a, b), bearing(A, B), TOL)
    assert _same(isc.meet_angle_s(a, b), meet_angle(A, B), TOL)


def test_ops_on_zero_and_infinite_ends():
    for a, b in [
        ((0.0, 0.0), (-1.0, 2.0)),
        ((1.0, 2.0), (0.0, math.inf)),
        ((-1.0, 3.0), (0.0, 0.0)),
    ]:
        assert _same(isc.div(a, b), _div(_IV(a), _IV(b)))
        assert _same(isc.mul(a, b), _IV(a) * _IV(b))
        assert _same(isc.bwd_mul(b, a, b), bwd_mul(_IV(b), _IV(a), _IV(b)))
    assert _same(isc.bearing((0.0, 0.0), (0.0, 0.0)), bearing(IV.of(0.0, 0.0), IV.of(0.0, 0.0)))


def _case(rng: np.random.Generator):
    """A true configuration and boxes around it (random widths, random offsets)."""
    xi, yi, thi = rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-4, 4)
    rho, beta = rng.uniform(0.2, 15), rng.uniform(-math.pi, math.pi)
    xj, yj = xi + rho * math.cos(thi + beta), yi + rho * math.sin(thi + beta)
    truth = (xi, yi, thi, xj, yj, rho, beta)
    wid = (2.0, 2.0, 0.6, 0.5, 0.5, 0.3, 0.1)
    boxes = []
    for v, w in zip(truth, wid, strict=True):
        r = w * rng.uniform(0.01, 1.0)
        off = rng.uniform(-r, r)
        boxes.append((v + off - r, v + off + r))
    return truth, boxes


def _feasible(boxes, rng, n=3000) -> np.ndarray:
    """Points of the relation inside every box: (xi, yi, thi, rho, beta) drawn, xj, yj
    computed, kept where they fall in their boxes."""
    b = np.array(boxes)
    xi, yi, thi = (rng.uniform(*b[k], n) for k in range(3))
    rho = rng.uniform(max(b[5, 0], 0.0), b[5, 1], n)  # a range: rho >= 0
    beta = rng.uniform(*b[6], n)
    xj, yj = xi + rho * np.cos(thi + beta), yi + rho * np.sin(thi + beta)
    ok = (b[3, 0] <= xj) & (xj <= b[3, 1]) & (b[4, 0] <= yj) & (yj <= b[4, 1])
    return np.stack([xi, yi, thi, xj, yj, rho, beta], axis=1)[ok]


@SEEDED
@given(st.integers(0, 2**32 - 1))
def test_range_bearing_matches_array_path_and_keeps_feasible_points(seed):
    rng = np.random.default_rng(seed)
    truth, boxes = _case(rng)
    ref = contract_range_bearing(*[_IV(b) for b in boxes])
    try:
        out = cps.contract_range_bearing(*boxes)
    except isc.Fallback:
        # Only where the array path proves something empty (its result then decides).
        assert any(bool(r.is_empty()) for r in ref)
        return
    for o, r in zip(out, ref, strict=True):
        assert _same(o, r, TOL)
    pts = np.vstack([np.array(truth)[None], _feasible(boxes, rng)])
    for k, (lo, hi) in enumerate(out):
        assert np.all((lo <= pts[:, k]) & (pts[:, k] <= hi))


def _localizer(scalar: bool) -> SlidingWindowCP:
    loc = SlidingWindowCP()
    loc.scalar_path = scalar
    return loc


@SEEDED
@given(st.integers(0, 2**32 - 1), st.integers(1, 3))
def test_relative_same_box_as_array_path(seed, peers):
    """SlidingWindowCP.relative over 1-3 peers at once, fast path vs array path."""
    rng = np.random.default_rng(seed)
    cases = [_case(rng) for _ in range(peers)]
    own = cases[0][1][:3]
    stamp = int(rng.integers(0, 10**8))
    results = []
    for scalar in (False, True):
        loc = _localizer(scalar)
        loc.start(0, *(_IV(b) for b in own))
        px, py, rho, beta = (
            IV.of([c[1][k][0] for c in cases], [c[1][k][1] for c in cases]) for k in (3, 4, 5, 6)
        )
        ok = loc.relative(stamp, px, py, rho, beta)
        results.append((ok, loc.current(), dict(loc.skipped)))
    (ok_a, box_a, sk_a), (ok_s, box_s, sk_s) = results
    assert ok_a == ok_s and sk_a == sk_s
    for a, s in zip(box_a, box_s, strict=True):
        assert _same((float(s.lo), float(s.hi)), a, TOL)


def test_relative_falls_back_on_unbounded_boxes():
    """No position known yet: the array path runs, with the same result."""
    out = []
    for scalar in (False, True):
        loc = _localizer(scalar)
        loc.start(0, None, None, IV.of(0.0, 0.1))
        loc.relative(0, IV.of(1.0, 1.5), IV.of(2.0, 2.5), IV.of(3.0, 3.2), IV.of(0.4, 0.5))
        out.append([(float(v.lo), float(v.hi)) for v in loc.current()])
    assert out[0] == out[1]


def _run(sc, scalar: bool, steps: int) -> list[PaperRobot]:
    old = SlidingWindowCP.scalar_path
    SlidingWindowCP.scalar_path = scalar
    try:
        robots = [PaperRobot(sc, i, window=20) for i in range(len(sc.names))]
        for s in range(steps):
            for r in robots:
                r.feed_own(r.own_messages(s))
            boxes = [r.box() for r in robots]
            for r in robots:
                for b in boxes:
                    r.feed_peer_box(b)
                r.cooperate(r.relative_messages(s, [n for n in sc.names if n != r.name]))
            for r in robots:
                r.record(s)
    finally:
        SlidingWindowCP.scalar_path = old
    return robots


def test_paper_scenario_same_boxes_and_containment():
    sc = simulate(duration_s=4.0, seed=3, errors="uniform")
    steps = sc.steps
    a, s = _run(sc, False, steps), _run(sc, True, steps)
    for ra, rs in zip(a, s, strict=True):
        la, ha = np.array(ra.tracks["multi_cp"].lo), np.array(ra.tracks["multi_cp"].hi)
        ls, hs = np.array(rs.tracks["multi_cp"].lo), np.array(rs.tracks["multi_cp"].hi)
        np.testing.assert_allclose(ls, la, rtol=0, atol=1e-12)
        np.testing.assert_allclose(hs, ha, rtol=0, atol=1e-12)
        truth = np.array(rs.truth)
        assert np.all((ls[:, :2] <= truth[:, :2]) & (truth[:, :2] <= hs[:, :2]))


def test_inconsistent_relative_is_refused_by_both_paths():
    """A peer 10 m away measured at 1 m: the scalar path proves nothing empty by itself,
    the array path decides, and both refuse it the same way."""
    out = []
    for scalar in (False, True):
        loc = _localizer(scalar)
        loc.start(0, IV.of(0.0, 0.1), IV.of(0.0, 0.1), IV.of(0.0, 0.1))
        ok = loc.relative(0, IV.of(10.0, 10.1), IV.of(0.0, 0.1), IV.of(1.0, 1.1), IV.of(0.0, 0.1))
        out.append((ok, dict(loc.skipped), [(float(v.lo), float(v.hi)) for v in loc.current()]))
    assert out[0] == out[1]
    assert out[0][0] is False


@SEEDED
@given(bound, width, st.floats(-0.5, 0.5), st.floats(0.0, 0.05), st.floats(-0.5, 0.5))
def test_odometry_displacement_matches_array_path(th, tw, r, rw, l):
    """The one-step prediction of SlidingWindowCP.step (eq. (2) forward), both paths."""
    from localization.contractors import odometry_displacement
    from localization.interval_trig import sinc_half

    th0, rr, ll, e = (th, th + tw), (r - rw, r + rw), (l - rw, l + rw), (0.33, 0.33)
    th1 = isc.add(th0, isc.div(isc.sub(rr, ll), e))
    ref = odometry_displacement(_IV(th0), _IV(th1), _IV(rr), _IV(ll), _IV(e), 0.5, True)
    out = cps.odometry_displacement(th0, th1, rr, ll, e, 0.5, True)
    for o, a in zip(out, ref, strict=True):
        assert _same(o, a, TOL)
    assert _same(isc.sinc_half((th, th + tw)), sinc_half(IV.of(th, th + tw)), TOL)
