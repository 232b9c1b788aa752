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
from localization.interval_trig import _RED_EPS, TRANS_MARGIN, TWO_PI, bearing_bounds

_INF = np.inf
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


#: The bearings of the box [yl, yh] x [xl, xh] without its origin (as ``bearing``).
bearing = bearing_bounds


def two_pi_times(k: np.ndarray) -> Pair:
    """Enclosure of 2 pi k for integer-valued float arrays ``k``."""
    a, b = k * TWO_PI, k * _TWO_PI_HI
    return _nx(np.minimum(a, b), -_INF), _nx(np.maximum(a, b), _INF)


def meet_angle_k(bl, bh, zl, zh) -> Pair:
    """``box`` met with the angle interval ``z`` modulo 2 pi
    (``localization.interval_trig.meet_angle``). Fast paths: a ``z`` of a whole turn or
    more leaves the box as it is; when box and z are each narrower than a turn only the
    branches k0 - 1, k0, k0 + 1 (k0 the nearest) can meet the box, and the result is the
    hull of those meets. Otherwise (a box wider than a turn, huge magnitudes) the general
    ``meet_angle``."""
    with np.errstate(invalid="ignore", over="ignore"):
        bm, zm = 0.5 * bl + 0.5 * bh, 0.5 * zl + 0.5 * zh
        wb, wz = bh - bl, zh - zl
        small = (np.abs(bm) < 1e6) & (np.abs(zm) < 1e6)
        full = wz >= TWO_PI
        fast = small & ((wb < TWO_PI - 1e-6) | full)
    if not fast.all():
        out = meet_angle(IV(np.asarray(bl, float), np.asarray(bh, float)), IV(zl, zh))
        return out.lo, out.hi
    k0 = np.round((bm - zm) / TWO_PI)
    if bool(np.all((wb + wz < TWO_PI - 1e-6) | full)):  # one branch at most: the nearest
        sl, sh = two_pi_times(k0)
        al, ah = add(zl, zh, sl, sh)
        return np.where(full, bl, np.maximum(bl, al)), np.where(full, bh, np.minimum(bh, ah))
    lo, hi = np.full(np.shape(bm), np.inf), np.full(np.shape(bm), -np.inf)
    for dk in (-1.0, 0.0, 1.0):
        sl, sh = two_pi_times(k0 + dk)
        al, ah = add(zl, zh, sl, sh)
        ml, mh = np.maximum(bl, al), np.minimum(bh, ah)
        hit = ml <= mh
        lo, hi = np.where(hit, np.minimum(lo, ml), lo), np.where(hit, np.maximum(hi, mh), hi)
    return np.where(full, bl, lo), np.where(full, bh, hi)
