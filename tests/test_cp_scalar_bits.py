"""The fused scalar range-bearing contraction (localization.cp_scalar over
localization.polar_scalar) against the op-by-op formulation it replaced
(tests/cp_scalar_ref.py, one interval_scalar call per operation): the same bits (float.hex,
so the signs of zeros too) or Fallback in the same cases, over seeded random boxes at
every scale with zero-width, signed-zero, straddling and quadrant-edge intervals; and
Fallback on empty, unbounded, NaN and out-of-range boxes. Each polar_scalar operation is
also checked bit for bit against its interval_scalar (or polar, op by op) version."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import localization.cp_scalar as cps
import localization.interval_scalar as isc
import localization.polar_scalar as ps
import tests.cp_scalar_ref as ref

SEEDED = settings(max_examples=400, derandomize=True, deadline=None, database=None)
Bits = tuple[str, str]


def _bits(iv: tuple[float, float]) -> Bits | None:
    """An interval's bits; None for any empty one."""
    return (iv[0].hex(), iv[1].hex()) if iv[0] <= iv[1] else None


def _run(f, boxes) -> list[Bits | None] | str:
    try:
        return [_bits(b) for b in f(*boxes)]
    except isc.Fallback:
        return "fallback"
    except (ValueError, OverflowError) as e:  # math.cos(inf) in the op-by-op formulation
        return type(e).__name__


def _random_boxes(rng: np.random.Generator) -> list[tuple[float, float]]:
    """(xi, yi, thi, xj, yj, rho, beta) around a true configuration at a random scale
    (1e-3 to 1e99 m: some bounds beyond +-1e100), with zero widths, signed-zero ends,
    peers next to the robot (dx, dy, rho straddling 0), bearings on a quadrant's edge,
    and boxes off the truth (some inconsistent)."""
    scale = 10.0 ** rng.choice([0, 0, 0, -3, 3, 6, 50, 99])
    xi, yi = rng.uniform(-10, 10, 2) * scale
    thi, beta = rng.uniform(-4, 4, 2)
    rho = (rng.uniform(0.2, 15) if rng.random() < 0.5 else rng.uniform(0, 0.3)) * scale
    if rng.random() < 0.2:
        beta = rng.integers(-4, 5) * 0.5 * math.pi - thi + rng.choice([0.0, 1e-15, -1e-9])
    truth = (xi, yi, thi, xi + rho * math.cos(thi + beta), yi + rho * math.sin(thi + beta))
    out = []
    for k, v in enumerate((*truth, rho, beta)):
        w = rng.choice([0.0, 1e-12, 0.01, 0.1, 1.0, 3.0, 8.0]) * rng.uniform(0, 1)
        w *= scale if k in (0, 1, 3, 4, 5) else 1.0
        off = rng.uniform(-w, w) * rng.choice([0.0, 1.0, 1.0, 4.0])
        lo, hi = float(v + off - w), float(v + off + w)
        if rng.random() < 0.04:
            lo = float(rng.choice([0.0, -0.0]))
        if rng.random() < 0.04:
            hi = float(rng.choice([0.0, -0.0]))
        out.append((lo, hi))
    return out


@pytest.mark.parametrize("seed", range(4))
def test_same_bits_as_the_op_by_op_formulation(seed):
    rng = np.random.default_rng(seed)
    seen: dict[str, int] = {}
    for _ in range(2500):
        boxes = _random_boxes(rng)
        old, new = _run(ref.contract_range_bearing, boxes), _run(cps.contract_range_bearing, boxes)
        if any(not abs(v) <= 1e100 for b in boxes for v in b) or any(
            not lo <= hi for lo, hi in boxes
        ):
            # Out of the fast path's range, or empty: Fallback (the array path decides);
            # the op-by-op formulation raised ValueError on empty headings.
            assert new == "fallback", boxes
            kind = "outside"
        else:
            assert new == old, boxes
            kind = "fallback" if new == "fallback" else "contracted"
        seen[kind] = seen.get(kind, 0) + 1
    assert seen["contracted"] > 1000 and seen["fallback"] > 300 and seen["outside"] > 100


BAD = [
    (0, (1.0, 0.0)),
    (1, (math.nan, 1.0)),
    (2, (0.1, math.nan)),
    (3, (-math.inf, 1.0)),
    (4, (0.0, math.inf)),
    (5, (1.0, math.inf)),
    (6, (-math.inf, math.inf)),
    (0, (-2e100, 0.0)),
    (5, (0.0, 1.5e100)),
    (5, (-1.0, -0.5)),  # rho below 0: empty range
]


@pytest.mark.parametrize(("k", "bad"), BAD)
def test_falls_back_on_empty_unbounded_nan_and_huge_boxes(k, bad):
    boxes = [(0.0, 0.1), (0.0, 0.1), (0.0, 0.1), (5.0, 5.1), (0.0, 0.5), (4.9, 5.2), (0.0, 0.1)]
    assert _run(cps.contract_range_bearing, boxes) != "fallback"
    boxes[k] = bad
    assert _run(cps.contract_range_bearing, boxes) == "fallback"


# Ends with exact and signed zeros, subnormals and ends at +-pi/2 multiples.
_end = st.one_of(
    st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 0.5 * math.pi, -math.pi, 3.0 * math.pi]),
    st.floats(-20.0, 20.0, allow_nan=False),
)
_iv = st.tuples(_end, _end).map(lambda t: (min(t), max(t)))


def _same(new: tuple[float, float], old: tuple[float, float]) -> bool:
    return _bits(new) == _bits(old)


@SEEDED
@given(_iv, _iv, _iv)
def test_ops_same_bits_as_interval_scalar(a, b, c):
    cl, ch, sl, sh = ps.cos_sin_f(*a)
    assert _same((cl, ch), isc.cos(a)) and _same((sl, sh), isc.sin(a))
    assert _same(ps.sqr_f(*a), isc.sqr(a))
    z = isc.meet(a, (0.0, math.inf))
    if z[0] <= z[1]:
        old = isc.bwd_sqr(z, b)
        try:
            assert _same(ps.bwd_sqr_f(*z, *b), old)
        except isc.Fallback:
            assert _bits(old) is None
    old = isc.bwd_mul(a, b, c)
    try:
        assert _same(ps.bwd_mul_f(*a, *b, *c), old)
    except isc.Fallback:
        assert _bits(old) is None
    assert _same(ps.bearing_f(*a, *b), isc.bearing(a, b))
    wa, wb = math.nextafter(a[1] - a[0], math.inf), math.nextafter(b[1] - b[0], math.inf)
    assert _same(ps.meet_angle_f(*a, *b, wa, wb), isc.meet_angle_s(a, b))


@SEEDED
@given(_iv, _iv, _iv)
def test_cone_same_bits_as_polar_cone(dx, dy, alpha):
    try:
        old = ref.cone(dx, dy, alpha)
    except isc.Fallback:
        old = None
    try:
        new = ps.cone_f(*dx, *dy, *alpha)
    except isc.Fallback:
        assert old is None
        return
    assert old is not None
    assert _same(new[:2], old[0]) and _same(new[2:], old[1])


H = math.pi / 2
# (dx, dy, alpha) boxes whose feasible points lie on a quadrant's edge (an axis), with one
# such point (x, y, angle): the cone's x tan t and y / tan t lose them at t = 0 and
# t = pi/2 (0 * inf, 0 / [0, b]) unless the edge is handled.
EDGES = [
    ((0.0, 0.0), (4.0, 6.0), (H - 0.1, H + 0.1), (0.0, 5.0, H)),
    ((4.0, 6.0), (0.0, 0.0), (-0.1, 0.1), (5.0, 0.0, 0.0)),
    ((2.0, 3.0), (0.0, 1.0), (0.0, 0.0), (2.5, 0.0, 0.0)),
    ((-6.0, -4.0), (0.0, 0.0), (math.pi - 0.1, math.pi + 0.1), (-5.0, 0.0, math.pi)),
    ((0.0, 0.0), (-6.0, -4.0), (-H - 0.1, -H + 0.1), (0.0, -5.0, -H)),
    ((0.0, 0.0), (4.0, 6.0), (H, H), (0.0, 5.0, H)),
    ((0.0, 1.0), (0.0, 0.0), (0.0, 0.3), (0.5, 0.0, 0.0)),
]


@pytest.mark.parametrize(("dx", "dy", "alpha", "point"), EDGES)
def test_the_cone_keeps_points_on_a_quadrants_edge(dx, dy, alpha, point):
    """Both paths (``polar.cone``/``contract_polar`` on arrays, ``polar_scalar.cone_f``
    and the fused range-bearing contraction on floats) keep a feasible point on an axis,
    and agree (the scalar path with its op-by-op reference bit for bit)."""
    from localization import polar
    from localization.interval import IV

    x, y, a = point
    r = math.hypot(x, y)
    iv = [IV.of(np.array([lo]), np.array([hi])) for lo, hi in (dx, dy, alpha)]
    cx, cy = polar.cone(*iv)
    assert cx.lo[0] <= x <= cx.hi[0] and cy.lo[0] <= y <= cy.hi[0]
    new = ps.cone_f(*dx, *dy, *alpha)
    # the array path's zeros may carry the other sign: equal as numbers
    assert new == (float(cx.lo[0]), float(cx.hi[0]), float(cy.lo[0]), float(cy.hi[0]))
    old = ref.cone(dx, dy, alpha)
    assert _same(new[:2], old[0]) and _same(new[2:], old[1])
    rho = (r - 1.0, r + 1.0)
    px, py, pr, pa = polar.contract_polar(*iv[:2], IV.of(np.array([rho[0]]), np.array([rho[1]])),
                                          iv[2])  # fmt: skip
    for box, v in ((px, x), (py, y), (pr, r), (pa, a)):
        assert box.lo[0] <= v <= box.hi[0], (box, v)
    # the robot at the origin heading alpha, bearing 0, sees the peer at (x, y)
    out = cps.contract_range_bearing((0.0, 0.0), (0.0, 0.0), alpha, dx, dy, rho, (0.0, 0.0))
    for (lo, hi), v in zip(out, (0.0, 0.0, a, x, y, r, 0.0), strict=True):
        assert lo <= v <= hi
