"""Interval operations of the polar contractor on bare floats, for the fused scalar
range-bearing contraction (``localization.cp_scalar.contract_range_bearing``): meets
of a sum or a difference, the meet of dx, dy with rho cos, rho sin, cos and sin of one
interval sharing their argument reduction, the square and its backward form, backward
multiplication, the bearing of a box, the narrow angle meet, and the quadrant cone of
``localization.polar.cone``. Each takes and returns interval ends as separate
floats (no tuples per operand) and is ``localization.interval_scalar``'s operation (or
``polar``'s, op by op) with the same outward rounding: one ``math.nextafter`` per
computed bound, libm's periodic functions widened by ``TRANS_MARGIN``, tan by
``_TAN_MARGIN``. Operand checks the callers make idle are left out (operands are
non-empty, finite and within +-1e100); where a product's or quotient's extremes follow
from its operands' signs only that corner is computed (rounding is monotone, and
``nextafter`` maps -0.0 and 0.0 to the same bound). Empty results raise
:class:`Fallback` where the op-by-op formulation would have ended in one.
"""

from __future__ import annotations

import math

from localization.interval_scalar import (
    _HALF_PI_HI,
    _HALF_PI_LO,
    _HALF_PI_PHASE,
    _INF,
    _PI_HI,
    _PI_LO,
    _TAN_MARGIN,
    _TWO_PI_C,
    _TWO_PI_HI,
    Fallback,
    Iv,
    _nx,
    bearing,
    bwd_mul,
    meet_angle_s,
)
from localization.interval_trig import _RED_EPS, TRANS_MARGIN, TWO_PI

Cs = tuple[float, float, float, float]  # cos's and sin's bounds of one interval
_NARROW = TWO_PI - 1e-6  # meet_angle_s's narrow case: widths summing below a turn
_TAN_DOWN, _TAN_UP = 1.0 - _TAN_MARGIN, 1.0 + _TAN_MARGIN
_TWO_PI_HI2 = 2.0 * _PI_HI
_cos, _sin, _tan, _atan2 = math.cos, math.sin, math.tan, math.atan2
_sqrt, _floor = math.sqrt, math.floor


def _arc(start: float) -> tuple[float, float, float, float]:
    """A quadrant's arc [start, start + 1/2] pi rounded outward (``polar._quadrant_angles``),
    its width as ``meet_angle_s`` computes it, and the unrounded arc's midpoint."""
    s_lo, s_hi = start * _PI_LO, (start + 0.5) * _PI_HI
    lo, hi = _nx(s_lo, -_INF), _nx(s_hi, _INF)
    return lo, hi, _nx(hi - lo, _INF), 0.5 * (s_lo + s_hi)


_ARCS = tuple(_arc(s) for s in (0.0, 0.5, 1.0, 1.5))


def cos_sin_f(lo: float, hi: float) -> Cs:
    """``interval_scalar.cos`` and ``sin`` of a finite non-empty [lo, hi]: (cos's lower
    and upper bound, sin's lower and upper bound), the argument reduced once. An extremum
    2 k pi + phase lies in [a, b] iff floor(b') >= a' (a', b' = a, b over 2 pi): the same
    test as ``_periodic``'s ceil(a') <= floor(b')."""
    w = _nx(hi - lo, _INF)
    if w >= TWO_PI:
        return -1.0, 1.0, -1.0, 1.0
    v1, v2, u1, u2 = _cos(lo), _cos(hi), _sin(lo), _sin(hi)
    r = _atan2(u1, v1)
    a = r - _RED_EPS
    b = r + w + _RED_EPS
    clo, chi = _periodic_ends(a, b, v1, v2)
    slo, shi = _periodic_ends(a - _HALF_PI_PHASE, b - _HALF_PI_PHASE, u1, u2)
    return clo, chi, slo, shi


def _periodic_ends(a: float, b: float, v1: float, v2: float) -> tuple[float, float]:
    """``_periodic``'s bounds from the reduced arc [a, b] (the phase taken off) and the
    values ``v1``, ``v2`` at the interval's ends: 1 where a maximum 2 k pi lies in the arc,
    -1 where a minimum 2 k pi + pi does, else the values widened by ``TRANS_MARGIN``."""
    if _floor(b / TWO_PI) >= a / TWO_PI:
        hi = 1.0
    else:
        hi = (v2 if v2 > v1 else v1) + TRANS_MARGIN
        hi = 1.0 if hi > 1.0 else hi
    if _floor((b - math.pi) / TWO_PI) >= (a - math.pi) / TWO_PI:
        return -1.0, hi
    lo = (v2 if v2 < v1 else v1) - TRANS_MARGIN
    return (-1.0 if lo < -1.0 else lo), hi


def meet_polar_f(
    dxl: float, dxh: float, dyl: float, dyh: float, rl: float, rh: float, cs: Cs
) -> tuple[float, float, float, float]:
    """dx & rho cos(alpha), dy & rho sin(alpha) for rho = [rl, rh] >= 0 and ``cs`` =
    :func:`cos_sin_f` of alpha (``interval_scalar.mul`` and ``meet_ne``: with rho >= 0 the
    product's extremes are the corners the cos and sin bounds' signs select);
    :class:`Fallback` on an empty result."""
    cl, ch, sl, sh = cs
    v = _nx(rl * cl if cl >= 0.0 else rh * cl, -_INF)
    dxl = dxl if dxl > v else v
    v = _nx(rh * ch if ch >= 0.0 else rl * ch, _INF)
    dxh = dxh if dxh < v else v
    v = _nx(rl * sl if sl >= 0.0 else rh * sl, -_INF)
    dyl = dyl if dyl > v else v
    v = _nx(rh * sh if sh >= 0.0 else rl * sh, _INF)
    dyh = dyh if dyh < v else v
    if not (dxl <= dxh and dyl <= dyh):
        raise Fallback
    return dxl, dxh, dyl, dyh


def sqr_f(lo: float, hi: float) -> tuple[float, float]:
    """``interval_scalar.sqr`` of a non-empty interval."""
    p, q = lo * lo, hi * hi
    m = _nx(p if p > q else q, _INF)
    if lo <= 0.0 <= hi:
        return 0.0, m
    lo = _nx(p if p < q else q, -_INF)
    return (lo if lo > 0.0 else 0.0), m


def bwd_sqr_f(zl: float, zh: float, xl: float, xh: float) -> tuple[float, float]:
    """``interval_scalar.bwd_sqr``: [xl, xh] under z = x^2 for a non-empty z;
    :class:`Fallback` on an empty result."""
    if zh < 0.0:
        raise Fallback
    rl = _nx(_sqrt(0.0 if zl < 0.0 else zl), -_INF)
    rl = 0.0 if rl < 0.0 else rl
    rh = _nx(_sqrt(zh), _INF)
    l1 = xl if xl > rl else rl
    h1 = xh if xh < rh else rh
    l2 = xl if xl > -rh else -rh
    h2 = xh if xh < -rl else -rl
    if l1 <= h1:
        if l2 <= h2:
            return (l2 if l2 < l1 else l1), (h2 if h2 > h1 else h1)
        return l1, h1
    if l2 <= h2:
        return l2, h2
    raise Fallback


def meet_sub_f(
    xl: float, xh: float, al: float, ah: float, bl: float, bh: float
) -> tuple[float, float]:
    """x & (a - b) for non-empty a, b (``interval_scalar.meet_ne`` of ``sub``);
    :class:`Fallback` on an empty result."""
    v = _nx(al - bh, -_INF)
    lo = xl if xl > v else v
    v = _nx(ah - bl, _INF)
    hi = xh if xh < v else v
    if not lo <= hi:
        raise Fallback
    return lo, hi


def meet_add_f(
    xl: float, xh: float, al: float, ah: float, bl: float, bh: float
) -> tuple[float, float]:
    """x & (a + b) for non-empty a, b (``interval_scalar.meet_ne`` of ``add``);
    :class:`Fallback` on an empty result."""
    v = _nx(al + bl, -_INF)
    lo = xl if xl > v else v
    v = _nx(ah + bh, _INF)
    hi = xh if xh < v else v
    if not lo <= hi:
        raise Fallback
    return lo, hi


def bwd_mul_f(zl: float, zh: float, xl: float, xh: float, yl: float, yh: float) -> Iv:
    """``interval_scalar.bwd_mul``: [xl, xh] under z = x * y, all non-empty;
    :class:`Fallback` on an empty result. For y without 0, z / y's extremes by sign."""
    if yl <= 0.0 <= yh:
        lo, hi = bwd_mul((zl, zh), (xl, xh), (yl, yh))
    else:
        if zl == 0.0 and zh == 0.0:
            ql = qh = 0.0
        elif yl > 0.0:
            ql = _nx(zl / yh if zl >= 0.0 else zl / yl, -_INF)
            qh = _nx(zh / yl if zh >= 0.0 else zh / yh, _INF)
        else:
            ql = _nx(zh / yh if zh >= 0.0 else zh / yl, -_INF)
            qh = _nx(zl / yl if zl >= 0.0 else zl / yh, _INF)
        lo = xl if xl > ql else ql
        hi = xh if xh < qh else qh
    if not lo <= hi:
        raise Fallback
    return lo, hi


def bearing_f(yl: float, yh: float, xl: float, xh: float) -> Iv:
    """``interval_scalar.bearing``: the bearings of the box y x x without the origin."""
    yl, yh, xl, xh = yl + 0.0, yh + 0.0, xl + 0.0, xh + 0.0
    if xl < 0.0 < xh and yl < 0.0 < yh:
        return -_PI_HI, _PI_HI
    if (yl == 0.0 or yh == 0.0) and (xl == 0.0 or xh == 0.0):
        return bearing((yl, yh), (xl, xh))  # a corner at the origin: left out
    c1, c2, c3, c4 = _atan2(yl, xl), _atan2(yl, xh), _atan2(yh, xl), _atan2(yh, xh)
    cut = xl < 0.0 and yl < 0.0 and yh >= 0.0
    if cut:
        c1 = c1 + TWO_PI if c1 <= 0.0 else c1
        c2 = c2 + TWO_PI if c2 <= 0.0 else c2
        c3 = c3 + TWO_PI if c3 <= 0.0 else c3
        c4 = c4 + TWO_PI if c4 <= 0.0 else c4
    lo = hi = c1
    for c in (c2, c3, c4):
        if c < lo:
            lo = c
        if c > hi:
            hi = c
    lo -= TRANS_MARGIN
    hi += TRANS_MARGIN
    floor, ceil = (0.0, _TWO_PI_HI2) if cut else (-_PI_HI, _PI_HI)
    return (floor if floor > lo else lo), (ceil if ceil < hi else hi)


def meet_angle_f(bl: float, bh: float, zl: float, zh: float, wb: float, wz: float) -> Iv:
    """``interval_scalar.meet_angle_s`` of non-empty [bl, bh] and [zl, zh] of widths
    ``wb``, ``wz`` (possibly empty)."""
    bm, zm = 0.5 * bl + 0.5 * bh, 0.5 * zl + 0.5 * zh
    if wb + wz < _NARROW and abs(bm) < 1e6 and abs(zm) < 1e6:
        k = float(round((bm - zm) / TWO_PI))
        if k != 0.0:
            a, b = k * TWO_PI, k * _TWO_PI_HI
            zl = _nx(zl + _nx(b if b < a else a, -_INF), -_INF)
            zh = _nx(zh + _nx(b if b > a else a, _INF), _INF)
        return (bl if bl > zl else zl), (bh if bh < zh else zh)
    return meet_angle_s((bl, bh), (zl, zh))


def _quadrant_f(
    al: float, ah: float, wb: float, q: int, pxl: float, pxh: float, pyl: float, pyh: float
) -> tuple[float, float, float, float] | None:
    """One quadrant of ``polar.cone``, mirrored into the first: the box [pxl, pxh] x
    [pyl, pyh] (both >= 0) within the angles alpha = [al, ah] (width ``wb``) meet there;
    None if nothing is."""
    arc_lo, arc_hi, wz, mid = _ARCS[q]
    lo, hi = meet_angle_f(al, ah, arc_lo, arc_hi, wb, wz)  # _quadrant_angles
    if not lo <= hi:
        return None
    if not (_nx(hi - lo, _INF) < math.pi):
        lo, hi = arc_lo, arc_hi
    else:
        k = float(round((0.5 * lo + 0.5 * hi - mid) / TWO_PI))
        a, b = k * TWO_PI, k * _TWO_PI_HI
        lo = _nx(lo - _nx(b if b > a else a, _INF), -_INF)
        hi = _nx(hi - _nx(b if b < a else a, -_INF), _INF)
        lo = lo if lo > arc_lo else arc_lo
        hi = hi if hi < arc_hi else arc_hi
        if not lo <= hi:
            return None
    if q == 1:  # _to_q1
        lo, hi = _nx(_PI_LO - hi, -_INF), _nx(_PI_HI - lo, _INF)
    elif q == 2:
        lo, hi = _nx(lo - _PI_HI, -_INF), _nx(hi - _PI_LO, _INF)
    elif q == 3:
        lo, hi = -_nx(hi - _TWO_PI_C[0], _INF), -_nx(lo - _TWO_PI_C[1], -_INF)
    lo = 0.0 if lo < 0.0 else lo  # _tan_q1
    lo = _HALF_PI_LO if lo > _HALF_PI_LO else lo
    hi = 0.0 if hi < 0.0 else hi
    hi = _HALF_PI_HI if hi > _HALF_PI_HI else hi
    tl = _tan(lo) * _TAN_DOWN
    tl = 0.0 if tl < 0.0 else tl
    th = _INF if hi >= _HALF_PI_LO else _tan(hi) * _TAN_UP
    if not tl <= th:
        return None  # tan empty
    # qy = py & px * tan (all >= 0: the product's extremes are its end products); at
    # t = pi/2 (tan inf) the cone holds every y >= 0 on x = 0 (polar._slope_up)
    v = _nx(pxl * tl, -_INF)
    qyl = pyl if pyl > v else v
    if th == _INF:
        qyh = pyh
    else:
        v = pxh * th
        v = _nx(0.0 if v != v else v, _INF)
        qyh = pyh if pyh < v else v
    # qx = px & py / tan; at t = 0 (tan 0) every x >= 0 on y = 0 (polar._slope_down)
    if pyl == 0.0 and pyh == 0.0:
        dl, dh = 0.0, (_INF if tl == 0.0 else 0.0)
    elif th == 0.0:
        dl, dh = 0.0, _INF
    else:
        dl = _nx(pyl / th, -_INF)
        dh = _INF if tl == 0.0 else _nx(pyh / tl, _INF)
    qxl = pxl if pxl > dl else dl
    qxh = pxh if pxh < dh else dh
    if not (qxl <= qxh and qyl <= qyh):
        return None
    return qxl, qxh, qyl, qyh


def cone_f(
    dxl: float, dxh: float, dyl: float, dyh: float, al: float, ah: float
) -> tuple[float, float, float, float]:
    """``polar.cone``: the box dx x dy met with the hull of what each quadrant it meets
    keeps within the angles alpha = [al, ah] (each mirrored into the first);
    :class:`Fallback` on an empty result."""
    inf = _INF
    wb = _nx(ah - al, inf)
    oxl = oyl = inf
    oxh = oyh = -inf
    pl = dxl if dxl > 0.0 else 0.0
    nl = -dxh if -dxh > 0.0 else 0.0
    x_pos = pl <= dxh
    x_neg = nl <= -dxl
    ul = dyl if dyl > 0.0 else 0.0
    ml = -dyh if -dyh > 0.0 else 0.0
    y_pos = ul <= dyh
    y_neg = ml <= -dyl
    for q, x_on, y_on in (
        (0, x_pos, y_pos),
        (1, x_neg, y_pos),
        (2, x_neg, y_neg),
        (3, x_pos, y_neg),
    ):
        if not (x_on and y_on):
            continue
        if q == 0 or q == 3:
            x0, x1 = pl, dxh
        else:
            x0, x1 = nl, -dxl
        y0, y1 = (ul, dyh) if q < 2 else (ml, -dyl)
        r = _quadrant_f(al, ah, wb, q, x0, x1, y0, y1)
        if r is None:
            continue
        x0, x1, y0, y1 = r
        if q == 1 or q == 2:
            x0, x1 = -x1, -x0
        if q >= 2:
            y0, y1 = -y1, -y0
        if x0 < oxl:
            oxl = x0
        if x1 > oxh:
            oxh = x1
        if y0 < oyl:
            oyl = y0
        if y1 > oyh:
            oyh = y1
    dxl = dxl if dxl > oxl else oxl
    dxh = dxh if dxh < oxh else oxh
    dyl = dyl if dyl > oyl else oyl
    dyh = dyh if dyh < oyh else oyh
    if not (dxl <= dxh and dyl <= dyh):
        raise Fallback
    return dxl, dxh, dyl, dyh
