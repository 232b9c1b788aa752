"""Scalar fast path of the cooperative contraction for one box (the daemon's case, one
robot's latest pose): the range-bearing contractor to peers (ekf-vs-cp.txt §2.4, the
cooperative constraints of eq. (5); ``localization.contractors.contract_range_bearing``
over ``localization.polar.contract_polar``) on Python floats instead of numpy arrays.

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

from localization.interval import IV, meet_angle
from localization.interval_trig import (
    _RED_EPS,
    _SINC_MAX2,
    _SINC_MIN,
    _U1,
    PI,
    TRANS_MARGIN,
    TWO_PI,
)

Iv = tuple[float, float]

_INF = math.inf
_nx = math.nextafter
_EMPTY: Iv = (_INF, -_INF)
EMPTY = _EMPTY  # the canonical empty interval
_PI_LO, _PI_HI = float(PI.lo), float(PI.hi)
_HALF_PI_LO, _HALF_PI_HI = 0.5 * math.pi, _nx(0.5 * math.pi, _INF)
_TWO_PI_HI = _nx(TWO_PI, _INF)
_TAN_MARGIN = 1e-14  # as localization.polar
_HALF_PI_PHASE = 0.5 * np.pi


class Fallback(Exception):
    """The fast path does not cover this case: run the array path."""


def _e(a: Iv) -> bool:
    return not (a[0] <= a[1])


def meet(a: Iv, b: Iv) -> Iv:
    al, ah = a
    bl, bh = b
    lo = al if al > bl else bl
    hi = ah if ah < bh else bh
    return (lo, hi) if lo <= hi else _EMPTY


def meet_ne(a: Iv, b: Iv) -> Iv:
    """Intersection that must not be empty (else :class:`Fallback`)."""
    al, ah = a
    bl, bh = b
    lo = al if al > bl else bl
    hi = ah if ah < bh else bh
    if not lo <= hi:
        raise Fallback
    return lo, hi


def hull(a: Iv, b: Iv) -> Iv:
    """Hull of the union, empties neutral."""
    if _e(a):
        return b
    if _e(b):
        return a
    return min(a[0], b[0]), max(a[1], b[1])


def add(a: Iv, b: Iv) -> Iv:
    al, ah = a
    bl, bh = b
    if not (al <= ah and bl <= bh):
        return _EMPTY
    return _nx(al + bl, -_INF), _nx(ah + bh, _INF)


def sub(a: Iv, b: Iv) -> Iv:
    al, ah = a
    bl, bh = b
    if not (al <= ah and bl <= bh):
        return _EMPTY
    return _nx(al - bh, -_INF), _nx(ah - bl, _INF)


def neg(a: Iv) -> Iv:
    return _EMPTY if _e(a) else (-a[1], -a[0])


def inflate(a: Iv, r: float) -> Iv:
    r = abs(r)
    return _EMPTY if _e(a) else (_nx(a[0] - r, -_INF), _nx(a[1] + r, _INF))


def _p(a: float, b: float) -> float:
    p = a * b
    return 0.0 if p != p else p  # 0 * inf: the real 0 times any real is 0


def mul(a: Iv, b: Iv) -> Iv:
    al, ah = a
    bl, bh = b
    if not (al <= ah and bl <= bh):
        return _EMPTY
    p1, p2, p3, p4 = al * bl, al * bh, ah * bl, ah * bh
    if p1 != p1 or p2 != p2 or p3 != p3 or p4 != p4:
        p1, p2, p3, p4 = _p(al, bl), _p(al, bh), _p(ah, bl), _p(ah, bh)
    return _nx(min(p1, p2, p3, p4), -_INF), _nx(max(p1, p2, p3, p4), _INF)


def _q(a: float, b: float) -> float:
    """a / b as numpy divides (NaN for 0/0 and inf/inf, signed inf for x/0)."""
    if b == 0.0:
        if a == 0.0 or a != a:
            return math.nan
        return math.copysign(_INF, a) * math.copysign(1.0, b)
    return a / b


def _fmin(*v: float) -> float:
    v2 = [x for x in v if x == x]
    return min(v2) if v2 else math.nan


def _fmax(*v: float) -> float:
    v2 = [x for x in v if x == x]
    return max(v2) if v2 else math.nan


def div(x: Iv, y: Iv) -> Iv:
    """x / y (``localization.interval_arith._div``)."""
    if _e(x) or _e(y):
        return _EMPTY
    xl, xh = x
    yl, yh = y
    if yl == 0.0 and yh == 0.0:
        return _EMPTY
    yl = 0.0 if yl == 0.0 else yl
    yh = -0.0 if yh == 0.0 else yh
    if xl == 0.0 and xh == 0.0:
        return 0.0, 0.0
    if yl < 0.0 < yh:
        return -_INF, _INF
    q = (_q(xl, yl), _q(xl, yh), _q(xh, yl), _q(xh, yh))
    lo, hi = _nx(_fmin(*q), -_INF), _nx(_fmax(*q), _INF)
    return (lo, hi) if lo <= hi else _EMPTY


def sqr(a: Iv) -> Iv:
    al, ah = a
    if not al <= ah:
        return _EMPTY
    p, q = al * al, ah * ah
    if al <= 0.0 <= ah:
        return 0.0, _nx(p if p > q else q, _INF)
    lo = _nx(p if p < q else q, -_INF)
    return (lo if lo > 0.0 else 0.0), _nx(p if p > q else q, _INF)


def sqrt(a: Iv) -> Iv:
    if _e(a) or a[1] < 0.0:
        return _EMPTY
    return (
        max(_nx(math.sqrt(max(a[0], 0.0)), -_INF), 0.0),
        _nx(math.sqrt(max(a[1], 0.0)), _INF),
    )


def bwd_sqr(z: Iv, x: Iv) -> Iv:
    r = sqrt(z)
    if _e(r):
        return _EMPTY
    return hull(meet(x, r), meet(x, neg(r)))


def bwd_mul(z: Iv, x: Iv, y: Iv) -> Iv:
    """x contracted under z = x * y (``localization.interval_arith.bwd_mul``)."""
    if _e(z) or _e(y) or _e(x):
        return _EMPTY
    zl, zh = z
    yl, yh = y
    y0 = yl <= 0.0 <= yh
    if not y0:
        return meet(x, div(z, y))
    if zl <= 0.0 <= zh:
        return x
    zpos = zl > 0.0
    num = zl if zpos else zh
    q_lo_y = _q(num, yl if yl < 0.0 else -_INF)
    q_hi_y = _q(num, yh if yh > 0.0 else _INF)
    q_lo_y = 0.0 if q_lo_y != q_lo_y else q_lo_y
    q_hi_y = 0.0 if q_hi_y != q_hi_y else q_hi_y
    left_end, right_end = (q_lo_y, q_hi_y) if zpos else (q_hi_y, q_lo_y)
    left_ok, right_ok = (yl < 0.0, yh > 0.0) if zpos else (yh > 0.0, yl < 0.0)
    left = (-_INF, _nx(left_end, _INF)) if left_ok else _EMPTY
    right = (_nx(right_end, -_INF), _INF) if right_ok else _EMPTY
    return hull(meet(x, left), meet(x, right))


def _periodic(a: Iv, f, phase: float) -> Iv:
    """cos (phase 0) or sin (phase pi/2) over a finite non-empty ``a``
    (``localization.interval_trig._periodic``)."""
    lo, hi = a
    v1, v2 = f(lo), f(hi)
    w = _nx(hi - lo, _INF)
    if w >= TWO_PI:
        return -1.0, 1.0
    r = math.atan2(math.sin(lo), math.cos(lo))
    s_lo = r - _RED_EPS - phase
    s_hi = r + w + _RED_EPS - phase
    has_max = math.ceil(s_lo / TWO_PI) <= math.floor(s_hi / TWO_PI)
    has_min = math.ceil((s_lo - math.pi) / TWO_PI) <= math.floor((s_hi - math.pi) / TWO_PI)
    out_hi = 1.0 if has_max else min(max(v1, v2) + TRANS_MARGIN, 1.0)
    out_lo = -1.0 if has_min else max(min(v1, v2) - TRANS_MARGIN, -1.0)
    return out_lo, out_hi


def cos(a: Iv) -> Iv:
    return _periodic(a, math.cos, 0.0)


def sin(a: Iv) -> Iv:
    return _periodic(a, math.sin, _HALF_PI_PHASE)


def bearing(y: Iv, x: Iv) -> Iv:
    """Bearings of the box y x x without the origin (``interval_trig.bearing_bounds``)."""
    yl, yh, xl, xh = y[0] + 0.0, y[1] + 0.0, x[0] + 0.0, x[1] + 0.0
    inside = xl < 0.0 < xh and yl < 0.0 < yh
    cut = xl < 0.0 and yl < 0.0 and yh >= 0.0 and not inside
    if inside:
        return -_PI_HI, _PI_HI
    cs = []
    for yy in (yl, yh):
        for xx in (xl, xh):
            if yy == 0.0 and xx == 0.0:
                continue  # the origin: left out
            c = math.atan2(yy, xx)
            cs.append(c + TWO_PI if cut and c <= 0.0 else c)
    if not cs:
        return -_PI_HI, _PI_HI
    lo = max(min(cs) - TRANS_MARGIN, 0.0 if cut else -_PI_HI)
    hi = min(max(cs) + TRANS_MARGIN, 2.0 * _PI_HI if cut else _PI_HI)
    return lo, hi


def meet_angle_s(box: Iv, z: Iv) -> Iv:
    """``box`` met with ``z`` modulo 2 pi (``interval_trig.meet_angle``); the narrow case
    here, any other through the array function."""
    if _e(box) or _e(z):
        return _EMPTY
    bm, zm = 0.5 * box[0] + 0.5 * box[1], 0.5 * z[0] + 0.5 * z[1]
    wb, wz = _nx(box[1] - box[0], _INF), _nx(z[1] - z[0], _INF)
    if wb + wz < TWO_PI - 1e-6 and abs(bm) < 1e6 and abs(zm) < 1e6:
        k = float(round((bm - zm) / TWO_PI))
        if k != 0.0:
            a, b = k * TWO_PI, k * _TWO_PI_HI
            z = add(z, (_nx(min(a, b), -_INF), _nx(max(a, b), _INF)))
        return meet(box, z)
    out = meet_angle(IV(np.array(box[0]), np.array(box[1])), IV(np.array(z[0]), np.array(z[1])))
    lo, hi = float(out.lo), float(out.hi)
    return (lo, hi) if lo <= hi else _EMPTY


_POS: Iv = (0.0, _INF)
_TWO_PI_IV: Iv = (TWO_PI, _TWO_PI_HI)
_TWO_PI_C: Iv = (_nx(2.0 * _PI_LO, -_INF), _nx(2.0 * _PI_HI, _INF))  # 2.0 * PI


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


def _sinc(u: float) -> float:
    return 1.0 if u == 0.0 else math.sin(u) / u


def sinc_half(d: Iv) -> Iv:
    """``interval_trig.sinc_half`` (sin(d/2)/(d/2)) for a finite non-empty ``d``."""
    dl, dh = d
    m = _nx(max(abs(dl), abs(dh)) * 0.5, _INF)
    mig = 0.0 if dl <= 0.0 <= dh else min(abs(dl), abs(dh))
    g = max(_nx(mig * 0.5, -_INF), 0.0)
    fm, fg = _sinc(m), _sinc(g)
    inv_g = _INF if g == 0.0 else _nx(1.0 / g, _INF)
    if g <= _U1:
        hi = max(fg + TRANS_MARGIN, _SINC_MAX2 if m > _U1 else -_INF)
    else:
        hi = min(inv_g, _SINC_MAX2)
    if m <= _U1:
        lo = fm - TRANS_MARGIN
    else:
        lo = max(-inv_g, _SINC_MIN) if g > _U1 else _SINC_MIN
    return lo, min(hi, 1.0)


def odometry_displacement(
    th0: Iv, th1: Iv, dsr: Iv, dsl: Iv, e: Iv, kappa: float, chord: bool
) -> tuple[Iv, Iv, Iv]:
    """``contractors.odometry_displacement`` (eq. (1)-(2) forward) for one step: finite
    non-empty operands, :class:`Fallback` otherwise."""
    for iv in (th0, th1, dsr, dsl, e):
        if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
            raise Fallback
    ds = mul(add(dsr, dsl), (0.5, 0.5))
    dth = meet_ne(div(sub(dsr, dsl), e), sub(th1, th0))
    phi = meet_ne(
        add(th0, mul(dth, (kappa, kappa))), sub(th1, mul(dth, (1.0 - kappa, 1.0 - kappa)))
    )
    length = mul(ds, sinc_half(dth)) if chord else ds
    if not (math.isfinite(length[0]) and math.isfinite(length[1])):
        raise Fallback
    return mul(length, cos(phi)), mul(length, sin(phi)), dth
