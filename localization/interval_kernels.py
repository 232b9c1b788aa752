"""Bare-array interval kernels for the hot loop of the window solver
(``localization.cp_rb_solve``): the operations of ``localization.interval`` on pairs of
numpy arrays ``(lo, hi)`` instead of :class:`~localization.interval.IV` objects.

Same arithmetic and the same outward rounding (one ``np.nextafter`` per computed bound,
libm's periodic functions widened by ``TRANS_MARGIN``), without the per-operation
bookkeeping of empties that makes an ``IV`` operation cost 10-100 us: a kernel costs a
few ufunc calls. The price is a precondition, stated per kernel: operands are non-empty
(``lo <= hi``) and, where said, finite. The callers keep it: they only intersect with
``meet`` and test the result with :func:`empty` once per contraction, and every value
they feed a kernel that asks for finite operands is finite by construction (ranges,
headings, displacement lengths). An empty intersection stays empty (``lo > hi``) through
the later kernels or becomes NaN, which :func:`empty` also reports.

``tests/test_interval_kernels.py`` checks each kernel against the ``IV`` operation it
mirrors (same bounds) and against sampled points.
"""

from __future__ import annotations

import numpy as np

from localization.interval import IV, meet_angle
from localization.interval_trig import _RED_EPS, TRANS_MARGIN, TWO_PI

_INF = np.inf
_PI_HI = float(np.nextafter(np.pi, _INF))
_TWO_PI_HI = float(np.nextafter(TWO_PI, _INF))
_nx = np.nextafter

Pair = tuple[np.ndarray, np.ndarray]


def down(a: np.ndarray) -> np.ndarray:
    return _nx(a, -_INF)


def up(a: np.ndarray) -> np.ndarray:
    return _nx(a, _INF)


def add(al, ah, bl, bh) -> Pair:
    return _nx(al + bl, -_INF), _nx(ah + bh, _INF)


def sub(al, ah, bl, bh) -> Pair:
    return _nx(al - bh, -_INF), _nx(ah - bl, _INF)


def mul(al, ah, bl, bh) -> Pair:
    """Product; finite operands."""
    p1, p2, p3, p4 = al * bl, al * bh, ah * bl, ah * bh
    lo = np.minimum(np.minimum(p1, p2), np.minimum(p3, p4))
    hi = np.maximum(np.maximum(p1, p2), np.maximum(p3, p4))
    return _nx(lo, -_INF), _nx(hi, _INF)


def meet(al, ah, bl, bh) -> Pair:
    """Intersection (``lo > hi`` where empty)."""
    return np.maximum(al, bl), np.minimum(ah, bh)


def hull(al, ah, bl, bh) -> Pair:
    """Hull of two non-empty intervals."""
    return np.minimum(al, bl), np.maximum(ah, bh)


def empty(lo, hi) -> np.ndarray:
    """Where the interval is empty (or NaN)."""
    return ~(lo <= hi)


def sqr(lo, hi) -> Pair:
    a, b = lo * lo, hi * hi
    z = (lo <= 0.0) & (hi >= 0.0)
    return np.where(z, 0.0, np.maximum(_nx(np.minimum(a, b), -_INF), 0.0)), _nx(
        np.maximum(a, b), _INF
    )


def sqrt(lo, hi) -> Pair:
    """sqrt of the non-negative part (hi >= 0)."""
    return (
        np.maximum(_nx(np.sqrt(np.maximum(lo, 0.0)), -_INF), 0.0),
        _nx(np.sqrt(np.maximum(hi, 0.0)), _INF),
    )


def bwd_sqr(zl, zh, xl, xh) -> Pair:
    """x contracted under z = x**2: x met with +-sqrt(z) (z >= 0 part)."""
    rl, rh = sqrt(zl, zh)
    pl, ph = np.maximum(xl, rl), np.minimum(xh, rh)
    nl, nh = np.maximum(xl, -rh), np.minimum(xh, -rl)
    pe, ne = ~(pl <= ph), ~(nl <= nh)
    lo = np.where(pe, nl, np.where(ne, pl, np.minimum(pl, nl)))
    hi = np.where(pe, nh, np.where(ne, ph, np.maximum(ph, nh)))
    return lo, hi


def cos_sin(lo, hi) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(cos lo, cos hi, sin lo, sin hi) over the interval: the values at its ends and
    every extremum inside (``localization.interval_trig.cos`` and ``sin``, one shared
    argument reduction); any width, unbounded ends give [-1, 1]."""
    fin = np.isfinite(lo) & np.isfinite(hi)
    allfin = bool(fin.all())
    if not allfin:
        lo, hi = np.where(fin, lo, 0.0), np.where(fin, hi, 0.0)
    c1, c2, s1, s2 = np.cos(lo), np.cos(hi), np.sin(lo), np.sin(hi)
    full = _nx(hi - lo, _INF) >= TWO_PI
    if not allfin:
        full = full | ~fin
    # extrema inside (libm's reduction of lo, as interval_trig._has_extrema)
    a = np.arctan2(s1, c1)
    s_lo, s_hi = a - _RED_EPS, a + _nx(hi - lo, _INF) + _RED_EPS
    ext = []
    for phase in (0.0, np.pi, 0.5 * np.pi, 1.5 * np.pi):  # cos max, min; sin max, min
        ext.append(np.ceil((s_lo - phase) / TWO_PI) <= np.floor((s_hi - phase) / TWO_PI))
    cmax, cmin, smax, smin = ext
    out = []
    for v1, v2, has_max, has_min in ((c1, c2, cmax, cmin), (s1, s2, smax, smin)):
        vlo = np.where(has_min | full, -1.0, np.maximum(np.minimum(v1, v2) - TRANS_MARGIN, -1.0))
        vhi = np.where(has_max | full, 1.0, np.minimum(np.maximum(v1, v2) + TRANS_MARGIN, 1.0))
        out += [vlo, vhi]
    return out[0], out[1], out[2], out[3]


def bearing(yl, yh, xl, xh) -> Pair:
    """The bearings of the box ``[yl, yh] x [xl, xh]`` without its origin
    (``localization.interval_trig.bearing``): one interval in [-pi, pi], or in
    [0, 2 pi] when the box reaches across the negative x-axis; the whole circle when the
    origin is inside the box or is the box."""
    yl, yh, xl, xh = yl + 0.0, yh + 0.0, xl + 0.0, xh + 0.0  # -0.0 -> +0.0
    inside = (xl < 0.0) & (xh > 0.0) & (yl < 0.0) & (yh > 0.0)
    cut = (xl < 0.0) & (yl < 0.0) & (yh >= 0.0) & ~inside
    cs = []
    for yy in (yl, yh):
        for xx in (xl, xh):
            c = np.arctan2(yy, xx)
            c = np.where(cut & (c <= 0.0), c + TWO_PI, c)
            cs.append(np.where((yy == 0.0) & (xx == 0.0), np.nan, c))
    with np.errstate(invalid="ignore"):
        c_lo = np.fmin(np.fmin(cs[0], cs[1]), np.fmin(cs[2], cs[3]))
        c_hi = np.fmax(np.fmax(cs[0], cs[1]), np.fmax(cs[2], cs[3]))
    none = np.isnan(c_lo)  # the box is the origin
    lo = np.maximum(c_lo - TRANS_MARGIN, np.where(cut, 0.0, -_PI_HI))
    hi = np.minimum(c_hi + TRANS_MARGIN, np.where(cut, 2.0 * _PI_HI, _PI_HI))
    whole = inside | none
    return np.where(whole, -_PI_HI, lo), np.where(whole, _PI_HI, hi)


def two_pi_times(k: np.ndarray) -> Pair:
    """Enclosure of 2 pi k for integer-valued float arrays ``k``."""
    a, b = k * TWO_PI, k * _TWO_PI_HI
    return _nx(np.minimum(a, b), -_INF), _nx(np.maximum(a, b), _INF)


def meet_angle_k(bl, bh, zl, zh) -> Pair:
    """``box`` met with the angle interval ``z`` modulo 2 pi
    (``localization.interval_trig.meet_angle``): when box and z together are narrower
    than a turn at most one branch of z meets the box, the nearest; otherwise (rare:
    wide or unbounded headings) the general ``meet_angle``."""
    with np.errstate(invalid="ignore", over="ignore"):
        bm, zm = 0.5 * bl + 0.5 * bh, 0.5 * zl + 0.5 * zh
        narrow = ((bh - bl) + (zh - zl) < TWO_PI - 1e-6) & (np.abs(bm) < 1e6) & (np.abs(zm) < 1e6)
    if not narrow.all():
        out = meet_angle(IV(np.asarray(bl, float), np.asarray(bh, float)), IV(zl, zh))
        return out.lo, out.hi
    sl, sh = two_pi_times(np.round((bm - zm) / TWO_PI))
    al, ah = add(zl, zh, sl, sh)
    return np.maximum(bl, al), np.minimum(bh, ah)
