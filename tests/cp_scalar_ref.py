"""The previous formulation of ``localization.cp_scalar.contract_range_bearing`` (up to
e943582): ``polar.contract_polar`` written op by op over ``localization.interval_scalar``
(one function call per interval operation), with the cone's edge rule added since
(``polar._slope_up``, ``polar._slope_down``: t = pi/2 holds every y on x = 0, t = 0
every x on y = 0). ``tests/test_cp_scalar_bits.py`` checks the fused fast version
against it bit for bit."""

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
        prod, quot = mul(px, tan_t), div(py, tan_t)
        if tan_t[1] == _INF:  # polar._slope_up: t = pi/2 holds every y on x = 0
            prod = (prod[0], _INF)
        if tan_t[0] == 0.0:  # polar._slope_down: t = 0 holds every x on y = 0
            quot = (0.0 if tan_t[1] == 0.0 else quot[0], _INF)
        qy = meet(py, prod)
        qx = meet(px, quot)
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
