"""Scalar fast path of the cooperative contraction for one box (the daemon's case, one
robot's latest pose): the range-bearing contractor to peers (ekf-vs-cp.txt §2.4, the
cooperative constraints of eq. (5); ``localization.contractors.contract_range_bearing``
over ``localization.polar.contract_polar``) on Python floats instead of numpy arrays (the operations on one interval are
``localization.interval_scalar``).

An interval is a pair ``(lo, hi)`` of floats. Every operation is the one of
``localization.interval_arith`` / ``localization.interval_trig`` written for one
interval, with the same outward rounding: one ``math.nextafter`` per computed bound,
libm's periodic functions widened by ``TRANS_MARGIN``, tan by ``_TAN_MARGIN``. The
results are therefore the array path's up to libm's last bit (math.cos may differ from
numpy's cos by an ulp, far inside the margin), and as sound.

The fast path covers the common case only: finite boxes, narrow angle meets, and no
interval proven empty along the way. Anything else raises :class:`Fallback`, and the
caller (``SlidingWindowCP.relative``) runs the array path, which handles every case;
the fallback decides nothing by itself, so the results never depend on which path ran
beyond libm's rounding. ``tests/test_cp_scalar.py`` checks the path against the array
path and against sampled feasible points.
"""

from __future__ import annotations

import math

import numpy as np

from localization.interval_scalar import (
    _EMPTY,
    _HALF_PI_HI,
    _HALF_PI_LO,
    _INF,
    _PI_HI,
    _PI_LO,
    _POS,
    _TAN_MARGIN,
    _TWO_PI_C,
    _TWO_PI_IV,
    Fallback,
    Iv,
    _e,
    _nx,
    add,
    bearing,
    bwd_mul,
    bwd_sqr,
    cos,
    div,
    hull,
    meet,
    meet_angle_s,
    meet_ne,
    mul,
    neg,
    sin,
    sinc_half,
    sqr,
    sub,
)
from localization.interval_trig import TWO_PI


def _quadrant_angles(alpha: Iv, start: float) -> Iv:
    """``polar._quadrant_angles`` for one interval."""
    s_lo, s_hi = start * _PI_LO, (start + 0.5) * _PI_HI
    arc = (_nx(s_lo, -_INF), _nx(s_hi, _INF))
    a = meet_angle_s(alpha, arc)
    if _e(a):
        return _EMPTY
    if not (_nx(a[1] - a[0], _INF) < np.pi):
        return arc
    k = float(round((0.5 * a[0] + 0.5 * a[1] - 0.5 * (s_lo + s_hi)) / TWO_PI))
    return meet(sub(a, mul((k, k), _TWO_PI_IV)), arc)


def _to_q1(t: Iv, start: float) -> Iv:
    if start == 0.0:
        return t
    if start == 0.5:
        return sub((_PI_LO, _PI_HI), t)
    if start == 1.0:
        return sub(t, (_PI_LO, _PI_HI))
    return neg(sub(t, _TWO_PI_C))


def _tan_q1(t: Iv) -> Iv:
    lo = min(max(t[0], 0.0), _HALF_PI_LO)
    hi = min(max(t[1], 0.0), _HALF_PI_HI)
    t_lo = max(math.tan(lo) * (1.0 - _TAN_MARGIN), 0.0)
    t_hi = _INF if hi >= _HALF_PI_LO else math.tan(hi) * (1.0 + _TAN_MARGIN)
    return (t_lo, t_hi) if t_lo <= t_hi else _EMPTY


_QUADRANTS = ((1.0, 1.0, 0.0), (-1.0, 1.0, 0.5), (-1.0, -1.0, 1.0), (1.0, -1.0, 1.5))


def cone(dx: Iv, dy: Iv, alpha: Iv) -> tuple[Iv, Iv]:
    """``polar.cone`` for one box."""
    out_x = out_y = None
    for sx, sy, start in _QUADRANTS:
        px = meet(dx if sx > 0 else neg(dx), _POS)
        py = meet(dy if sy > 0 else neg(dy), _POS)
        if _e(px) or _e(py):
            continue
        ang = _quadrant_angles(alpha, start)
        if _e(ang):
            continue
        t = _to_q1(ang, start)
        tan_t = _tan_q1(t) if not _e(t) else _EMPTY
        qy = meet(py, mul(px, tan_t))
        qx = meet(px, div(py, tan_t))
        if _e(qx) or _e(qy) or _e(t):
            qx = qy = _EMPTY
        qx, qy = (qx if sx > 0 else neg(qx)), (qy if sy > 0 else neg(qy))
        out_x = qx if out_x is None else hull(out_x, qx)
        out_y = qy if out_y is None else hull(out_y, qy)
    if out_x is None or out_y is None:
        raise Fallback
    return meet_ne(dx, out_x), meet_ne(dy, out_y)


def contract_polar(dx: Iv, dy: Iv, rho: Iv, alpha: Iv) -> tuple[Iv, Iv, Iv, Iv]:
    """One pass of ``polar.contract_polar`` for rho >= 0 (a range); :class:`Fallback` on
    an empty result."""
    cal, sal = cos(alpha), sin(alpha)
    dx = meet_ne(dx, mul(rho, cal))
    dy = meet_ne(dy, mul(rho, sal))
    r2 = meet_ne(sqr(rho), add(sqr(dx), sqr(dy)))
    dx = bwd_sqr(meet(sqr(dx), sub(r2, sqr(dy))), dx)
    dy = bwd_sqr(meet(sqr(dy), sub(r2, sqr(dx))), dy)
    rho = bwd_sqr(r2, rho)
    if _e(dx) or _e(dy) or _e(rho):
        raise Fallback
    free = rho[0] <= 0.0 <= rho[1] and dx[0] <= 0.0 <= dx[1] and dy[0] <= 0.0 <= dy[1]
    if not free:
        alpha = meet_angle_s(alpha, bearing(dy, dx))
        if _e(alpha):
            raise Fallback
    dx, dy = cone(dx, dy, alpha)
    cal, sal = cos(alpha), sin(alpha)
    dx = meet_ne(dx, mul(rho, cal))
    dy = meet_ne(dy, mul(rho, sal))
    rho = bwd_mul(dx, rho, cal)
    rho = bwd_mul(dy, rho, sal)
    if _e(rho):
        raise Fallback
    return dx, dy, rho, alpha


def contract_range_bearing(
    xi: Iv, yi: Iv, thi: Iv, xj: Iv, yj: Iv, rho: Iv, beta: Iv
) -> tuple[Iv, Iv, Iv, Iv, Iv, Iv, Iv]:
    """``contractors.contract_range_bearing`` (one polar pass) for one box."""
    rho = meet_ne(rho, _POS)
    dx, dy, rho, alpha = contract_polar(sub(xj, xi), sub(yj, yi), rho, add(thi, beta))
    thi = meet_ne(thi, sub(alpha, beta))
    beta = meet_ne(beta, sub(alpha, thi))
    xi = meet_ne(xi, sub(xj, dx))
    yi = meet_ne(yi, sub(yj, dy))
    xj = meet_ne(xj, add(xi, dx))
    yj = meet_ne(yj, add(yi, dy))
    return xi, yi, thi, xj, yj, rho, beta


def _width(a: Iv) -> float:
    return _nx(a[1] - a[0], _INF)


def relative_fixpoint(
    own: tuple[Iv, Iv, Iv], peers: list[tuple[Iv, Iv, Iv, Iv]], tol: float, max_iter: int
) -> tuple[Iv, Iv, Iv]:
    """``contractors.fixpoint`` of the range-bearing contractor of one box ``own`` =
    (x, y, theta) against every peer (peer x, peer y, rho, beta): each peer contracts its
    own copy of the box, all passes stop together (the largest relative shrink over every
    peer's intervals), and the box is the meet of the copies. Finite bounds only;
    :class:`Fallback` otherwise or on any empty."""
    for iv in own:
        if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
            raise Fallback
    cur = []
    for p in peers:
        for iv in p:
            if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
                raise Fallback
        cur.append((*own, *p))
    for _ in range(max_iter):
        new = [contract_range_bearing(*c) for c in cur]
        shrink = 0.0
        for c, n in zip(cur, new, strict=True):
            for a, b in zip(c, n, strict=True):
                wa = _width(a)
                rel = (wa - _width(b)) / max(wa, 1e-12)
                if rel > shrink:
                    shrink = rel
        cur = new
        if shrink <= tol:
            break
    out = []
    for i in range(3):
        lo = max(c[i][0] for c in cur)
        hi = min(c[i][1] for c in cur)
        if not lo <= hi:
            raise Fallback
        out.append((lo, hi))
    return out[0], out[1], out[2]


def odometry_displacement(
    th0: Iv, th1: Iv, dsr: Iv, dsl: Iv, e: Iv, kappa: float, chord: bool
) -> tuple[Iv, Iv, Iv]:
    """``contractors.odometry_displacement`` (eq. (1)-(2) forward) for one step: finite
    non-empty operands, :class:`Fallback` otherwise."""
    for iv in (th0, th1, dsr, dsl, e):
        if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
            raise Fallback
    ds = mul(add(dsr, dsl), (0.5, 0.5))
    return displacement_dth(th0, th1, ds, div(sub(dsr, dsl), e), kappa, chord)


def displacement_dth(
    th0: Iv, th1: Iv, ds: Iv, dth: Iv, kappa: float, chord: bool
) -> tuple[Iv, Iv, Iv]:
    """eq. (2) forward from finite non-empty headings ``th0``, ``th1`` and the step's
    wheel terms of eq. (1), ``ds`` = (dSr + dSl)/2 and ``dth`` = (dSr - dSl)/e:
    (dx, dy, dtheta), :class:`Fallback` on an empty or unbounded result. The meets,
    sums and products by the point ``kappa`` written out (the same operations as
    meet_ne, add, sub and mul: one ``nextafter`` per bound)."""
    a0, b0 = th0
    a1, b1 = th1
    # dth = dth & (th1 - th0)
    lo, hi = _nx(a1 - b0, -_INF), _nx(b1 - a0, _INF)
    dl = dth[0] if dth[0] > lo else lo
    dh = dth[1] if dth[1] < hi else hi
    if not dl <= dh:
        raise Fallback
    # phi = (th0 + dth * kappa) & (th1 - dth * (1 - kappa))
    k0, k1 = dl * kappa, dh * kappa
    m0, m1 = (k0, k1) if k0 <= k1 else (k1, k0)
    u = 1.0 - kappa
    k0, k1 = dl * u, dh * u
    n0, n1 = (k0, k1) if k0 <= k1 else (k1, k0)
    lo = _nx(a0 + _nx(m0, -_INF), -_INF)
    hi = _nx(b0 + _nx(m1, _INF), _INF)
    lo2 = _nx(a1 - _nx(n1, _INF), -_INF)
    hi2 = _nx(b1 - _nx(n0, -_INF), _INF)
    if lo2 > lo:
        lo = lo2
    if hi2 < hi:
        hi = hi2
    if not lo <= hi:
        raise Fallback
    phi = (lo, hi)
    d = (dl, dh)
    length = mul(ds, sinc_half(d)) if chord else ds
    if not (math.isfinite(length[0]) and math.isfinite(length[1])):
        raise Fallback
    return mul(length, cos(phi)), mul(length, sin(phi)), d


def displacement(th0: Iv, th1: Iv, ds: Iv, dth: Iv, kappa: float, chord: bool) -> tuple[Iv, Iv]:
    """:func:`displacement_dth` without dtheta: the (dx, dy) of a window step."""
    dx, dy, _ = displacement_dth(th0, th1, ds, dth, kappa, chord)
    return dx, dy
