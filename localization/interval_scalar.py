"""Interval arithmetic on Python floats for one interval at a time: the operations of
``localization.interval_arith`` and ``localization.interval_trig`` (meet, hull, + - * /,
sqr, sqrt and their backward forms, cos, sin, bearing, angle meets, sinc_half) written
for a pair ``(lo, hi)`` instead of numpy arrays, with the same outward rounding: one
``math.nextafter`` per computed bound, libm's periodic functions widened by
``TRANS_MARGIN``. Used by the scalar fast path of CP (``localization.cp_scalar``), where
numpy's per-call cost on one interval dominated. Where an operation would need a case
the fast path does not cover, it raises :class:`Fallback` and the caller runs the array
path. ``tests/test_cp_scalar.py`` checks each operation against its array version.
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


def around(mid: float, rad: float) -> Iv:
    """``IV.around``: [mid - |rad|, mid + |rad|] rounded outward (empty if NaN)."""
    r = abs(rad)
    lo, hi = _nx(mid - r, -_INF), _nx(mid + r, _INF)
    return (lo, hi) if lo <= hi else _EMPTY


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
