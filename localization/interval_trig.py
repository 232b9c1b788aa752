"""Periodic functions and angle intervals for the interval solver of ekf-vs-cp.txt eq. (5):
cos and sin of the heading in eq. (2), the bearing (atan2) of the range-bearing
measurements, the chord factor of eq. (2), and their backward projections.

Angles are plain real intervals (not wrapped): a heading box of width 10 means 10
radians of uncertainty. Every periodic operation handles every branch:

- ``cos``/``sin`` reduce the lower end modulo 2*pi (through libm's own sin/cos, exact
  for any magnitude) and look for extrema in the reduced interval; a box spanning a full
  period gives [-1, 1];
- ``meet_angle(box, z)`` is the hull of ``box ∩ (z + 2*pi*k)`` over *every* integer k
  (found from the two ends, so a box of any width or a half-line costs the same);
  ``bwd_cos``/``bwd_sin`` are ``meet_angle`` with the two acos/asin branches;
- ``bearing`` returns the bearings of a box (its origin excluded) as one interval of
  width <= pi (in [-pi, pi], or in [0, 2*pi] when the box reaches across the negative
  x-axis), or the whole circle when the origin is inside (or is the box); contractors
  meet it into an angle with ``meet_angle``. ``atan2`` adds libm's atan2(0, 0) = 0.

libm's sin, cos, atan2, acos and asin are not correctly rounded but accurate to a few
ulp; their bounds are widened by ``TRANS_MARGIN`` (an absolute margin far above that)
and clipped to their true ranges. pi and 2*pi are used as enclosing intervals.
"""

from __future__ import annotations

import numpy as np

from localization.interval_arith import IV, _arr, _mask, as_iv, down, up

TWO_PI = 2.0 * np.pi  # float(2 pi) < 2 pi
# Absolute outward margin for the transcendental functions (libm error is < 4 ulp of 1).
TRANS_MARGIN = 1e-14
PI = IV(np.array(np.pi), np.array(up(np.pi)))  # float(pi) < pi < next float
HALF_PI = IV(np.array(0.5 * np.pi), np.array(up(0.5 * np.pi)))
TWO_PI_IV = IV(np.array(TWO_PI), np.array(up(TWO_PI)))
_INF = np.inf
# Slack of the extremum search in reduced coordinates: far above the reduction error
# (~1e-15); a false extremum costs at most _RED_EPS**2 / 2 on a bound.
_RED_EPS = 1e-13
# sinc(u) = sin(u)/u decreases on [0, _U1] (_U1: first root of tan u = u) to its global
# minimum _SINC_MIN; for |u| >= _U1 it stays below _SINC_MAX2 (its next maximum).
_U1 = 4.4934094579
_SINC_MIN = -0.2172336283
_SINC_MAX2 = 0.1283745536


def _two_pi_times(k) -> IV:
    """Enclosure of 2*pi*k for integer-valued float arrays ``k``."""
    return IV.of(k) * TWO_PI_IV


# --- cos and sin ---------------------------------------------------------------------
def _has_extrema(lo: np.ndarray, hi: np.ndarray, phase: float) -> tuple[np.ndarray, ...]:
    """Whether [lo, hi] (finite, narrower than 2*pi) may hold a maximum (phase + 2k*pi)
    or a minimum (phase + pi + 2k*pi) of cos(t - phase). ``lo`` is reduced to [-pi, pi]
    by atan2(sin lo, cos lo) (error ~1e-15 for any magnitude); the search is widened by
    _RED_EPS, so it never misses one."""
    a = np.arctan2(np.sin(lo), np.cos(lo))
    with np.errstate(over="ignore", invalid="ignore"):
        w = up(hi - lo)
    s_lo = a - _RED_EPS - phase
    s_hi = a + w + _RED_EPS - phase
    has_max = np.ceil(s_lo / TWO_PI) <= np.floor(s_hi / TWO_PI)
    has_min = np.ceil((s_lo - np.pi) / TWO_PI) <= np.floor((s_hi - np.pi) / TWO_PI)
    return has_max, has_min


def _periodic(x: IV, f, phase: float) -> IV:
    """f(x) for f = cos (phase 0) or sin (phase pi/2), f(t) = cos(t - phase)."""
    e = x.is_empty()
    fin = np.isfinite(x.lo) & np.isfinite(x.hi) & ~e
    lo_x = np.where(fin, x.lo, 0.0)
    hi_x = np.where(fin, x.hi, 0.0)
    v1, v2 = f(lo_x), f(hi_x)
    with np.errstate(over="ignore"):
        full = ~fin | (up(hi_x - lo_x) >= TWO_PI)
    has_max, has_min = _has_extrema(lo_x, hi_x, phase)
    hi = np.where(has_max | full, 1.0, np.minimum(np.maximum(v1, v2) + TRANS_MARGIN, 1.0))
    lo = np.where(has_min | full, -1.0, np.maximum(np.minimum(v1, v2) - TRANS_MARGIN, -1.0))
    return _mask(IV(lo, hi), e)


def cos(x: IV) -> IV:
    """cos over x: the values at the ends and every extremum (k*pi) inside."""
    return _periodic(x, np.cos, 0.0)


def sin(x: IV) -> IV:
    """sin over x: the values at the ends and every extremum (pi/2 + k*pi) inside."""
    return _periodic(x, np.sin, 0.5 * np.pi)


# --- bearings ------------------------------------------------------------------------
def bearing(y: IV, x: IV) -> IV:
    """The bearings of the points of the box ``y x x`` other than the origin, as one
    interval: in [-pi, pi] normally, in [0, 2*pi] when the box reaches across the
    negative x-axis (the branch cut); the whole circle [-pi, pi] when the origin is
    inside the box, and for the box {origin} itself (the polar relation holds there for
    every angle).

    The extreme bearings are at corners (the origin excluded when it is one): the
    angle is continuous on the box in the chosen representation, and the box without
    the origin lies in a closed half-plane. Unbounded boxes are fine: the corner
    values are the limits (atan2 of infinities).
    """
    e = y.is_empty() | x.is_empty()
    yl, yh, xl, xh = np.broadcast_arrays(y.lo, y.hi, x.lo, x.hi)
    # placeholders for empties
    yl, yh = np.where(e, 0.0, yl), np.where(e, 0.0, yh)
    xl, xh = np.where(e, 1.0, xl), np.where(e, 1.0, xh)
    lo, hi = bearing_bounds(yl, yh, xl, xh)
    return _mask(IV(lo, hi), e)


def bearing_bounds(yl, yh, xl, xh) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bearing` on bare arrays of non-empty intervals (also the window solver's
    kernel, ``localization.interval_kernels.bearing``)."""
    yl, yh, xl, xh = yl + 0.0, yh + 0.0, xl + 0.0, xh + 0.0  # atan2(-0., x<0) would give -pi
    inside = (xl < 0.0) & (xh > 0.0) & (yl < 0.0) & (yh > 0.0)
    # Across the negative x-axis angles are counted in [0, 2pi): the box then has points
    # with x < 0 below and on or above the axis (and, the origin not inside, no point
    # with x > 0 above it: direction 0 is reached from below, as 2pi).
    cut = (xl < 0.0) & (yl < 0.0) & (yh >= 0.0) & ~inside
    cs = []
    for yy in (yl, yh):
        for xx in (xl, xh):
            c = np.arctan2(yy, xx)
            c = np.where(cut & (c <= 0.0), c + TWO_PI, c)
            cs.append(np.where((yy == 0.0) & (xx == 0.0), np.nan, c))  # the origin: left out
    with np.errstate(invalid="ignore"):
        c_lo = np.fmin(np.fmin(cs[0], cs[1]), np.fmin(cs[2], cs[3]))
        c_hi = np.fmax(np.fmax(cs[0], cs[1]), np.fmax(cs[2], cs[3]))
    none = np.isnan(c_lo)  # the box is the origin
    pi_hi = float(PI.hi)
    lo = np.maximum(c_lo - TRANS_MARGIN, np.where(cut, 0.0, -pi_hi))
    hi = np.minimum(c_hi + TRANS_MARGIN, np.where(cut, 2.0 * pi_hi, pi_hi))
    whole = inside | none
    return np.where(whole, -pi_hi, lo), np.where(whole, pi_hi, hi)


def atan2(y: IV, x: IV, ref=None) -> IV:
    """The values of atan2 over the box ``y x x``: :func:`bearing`, plus libm's
    atan2(0, 0) = 0 when the origin is in the box. With ``ref`` the result is shifted
    by the multiple of 2*pi that brings it next to ``ref``."""
    b = bearing(y, x)
    origin = y.contains(0.0) & x.contains(0.0)
    # In the [0, 2pi] representation (an upper end beyond pi) 0 may be taken as 2pi.
    as_2pi = (b.hi > PI.hi) & (TWO_PI - b.lo < b.hi)
    lo = np.where(origin & ~as_2pi, np.minimum(b.lo, 0.0), b.lo)
    hi = np.where(origin, np.where(as_2pi, TWO_PI_IV.hi, np.maximum(b.hi, 0.0)), b.hi)
    out = IV(lo, hi)._canon()
    return out if ref is None else align_angle(out, ref)


# --- angles modulo 2*pi ----------------------------------------------------------------
def align_angle(a: IV, ref) -> IV:
    """``a`` shifted by the multiple of 2*pi that brings its centre closest to ``ref``
    (the same set of angles modulo 2*pi)."""
    k = np.round((_arr(ref) - a.mid()) / TWO_PI)
    k = np.where(np.isfinite(k), k, 0.0)
    if not k.any() and np.shape(k) == a.shape:
        return a
    return a + _two_pi_times(k)


_OFFSETS = np.arange(-2.0, 3.0)


def _first_branch(box_lo: np.ndarray, z: IV) -> np.ndarray:
    """The least point >= ``box_lo`` (finite) of the union of the branches
    z + 2*pi*k, rounded down (``box_lo`` itself if it lies in one; a branch's lower end
    otherwise). k is guessed in floats and checked on the rigorous enclosures of the
    branches guess-2 .. guess+2: the first one reaching ``box_lo`` wins, provided
    guess-2 does not (else, as for huge magnitudes, no contraction: ``box_lo``)."""
    with np.errstate(invalid="ignore", over="ignore"):
        kg = np.ceil((box_lo - z.hi) / TWO_PI)
    ok = np.isfinite(kg) & (np.abs(kg) < 2.0**52)
    kg = np.where(ok, kg, 0.0)
    offs = _OFFSETS.reshape((5,) + (1,) * np.ndim(kg))
    b = z + _two_pi_times(kg + offs)  # the 5 candidate branches, stacked on axis 0
    meets = b.hi >= box_lo  # the true branch reaches box_lo only if this holds
    first = np.argmax(meets, axis=0)[None]
    out = np.maximum(box_lo, np.take_along_axis(b.lo, first, axis=0)[0])
    bad = ~ok | meets[0] | ~np.any(meets, axis=0)
    return np.where(bad, box_lo, out)


def meet_angle(box: IV, z: IV) -> IV:
    """``box`` met with the angle interval ``z`` modulo 2*pi: the hull of
    ``box ∩ (z + 2*pi*k)`` over every integer k. ``z`` spanning a full period (or
    unbounded) leaves ``box`` as it is; an unbounded ``box`` keeps its infinite ends.
    Empty if no branch meets the box."""
    z = as_iv(z)
    with np.errstate(over="ignore", invalid="ignore"):
        narrow = (box.width() + z.width() < TWO_PI - 1e-6) & (np.abs(box.mid()) < 1e6)
    if np.all(narrow & (np.abs(z.mid()) < 1e6)):
        # Branches 2*pi apart, wider than box + z together: at most one meets the box,
        # the one whose centre is nearest (within pi - 5e-7, far above float error).
        return box & align_angle(z, box.mid())
    shape = np.broadcast_shapes(box.shape, z.shape)
    bl, bh = np.broadcast_to(box.lo, shape), np.broadcast_to(box.hi, shape)
    zb = IV(np.broadcast_to(z.lo, shape), np.broadcast_to(z.hi, shape))
    zf = np.isfinite(zb.lo) & np.isfinite(zb.hi)
    zs = IV(np.where(zf, zb.lo, 0.0), np.where(zf, zb.hi, 0.0))  # finite stand-ins
    with np.errstate(over="ignore", invalid="ignore"):
        full = ~zf | (up(zs.hi - zs.lo) >= TWO_PI)
    lo = np.where(np.isfinite(bl), _first_branch(np.where(np.isfinite(bl), bl, 0.0), zs), bl)
    # The last point <= bh: minus the first point >= -bh of the mirrored branches.
    neg_bh = np.where(np.isfinite(bh), -bh, 0.0)
    hi = np.where(np.isfinite(bh), -_first_branch(neg_bh, -zs), bh)
    lo = np.where(full, bl, lo)
    hi = np.where(full, bh, hi)
    return _mask(IV(lo, hi), box.is_empty() | z.is_empty())


# --- chord factor of eq. (2) ---------------------------------------------------------
def _sinc(u: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(u == 0.0, 1.0, np.sin(u) / np.where(u == 0.0, 1.0, u))


def sinc_half(d: IV) -> IV:
    """sin(d/2)/(d/2), the chord-to-arc ratio of a turn by ``d`` (1 at d = 0).

    With u = |d|/2 in [g, m]: sinc decreases on [0, _U1] (a turn below ~1.43 turns), so
    the range is [sinc(m), sinc(g)]; beyond, it stays in [_SINC_MIN, _SINC_MAX2] and
    within +-1/u (a guaranteed enclosure, not the tightest)."""
    m = up(d.mag() * 0.5)
    g = np.maximum(down(d.mig() * 0.5), 0.0)
    fm, fg = _sinc(np.where(np.isfinite(m), m, 0.0)), _sinc(g)
    with np.errstate(divide="ignore", over="ignore"):
        inv_g = up(1.0 / g)
    hi = np.where(
        g <= _U1,
        np.maximum(fg + TRANS_MARGIN, np.where(m > _U1, _SINC_MAX2, -_INF)),
        np.minimum(inv_g, _SINC_MAX2),
    )
    lo = np.where(
        m <= _U1,
        fm - TRANS_MARGIN,
        np.where(g > _U1, np.maximum(-inv_g, _SINC_MIN), _SINC_MIN),
    )
    return _mask(IV(lo, np.minimum(hi, 1.0)), d.is_empty())


# --- inverse (backward) projections used by the HC4 contractors ----------------------
def bwd_cos(z: IV, x: IV) -> IV:
    """Contract x under z = cos(x), over every branch: x = ±acos(z) + 2*pi*k."""
    zl, zh = np.maximum(z.lo, -1.0), np.minimum(z.hi, 1.0)
    e = z.is_empty() | (zl > zh)
    zl, zh = np.where(e, -1.0, zl), np.where(e, 1.0, zh)
    a = IV(
        np.maximum(np.arccos(zh) - TRANS_MARGIN, 0.0),
        np.minimum(np.arccos(zl) + TRANS_MARGIN, PI.hi),
    )
    out = meet_angle(x, a) | meet_angle(x, -a)
    whole = (zl <= -1.0) & (zh >= 1.0)
    out = IV(np.where(whole, x.lo, out.lo), np.where(whole, x.hi, out.hi))
    return _mask(out, e | x.is_empty())


def bwd_sin(z: IV, x: IV) -> IV:
    """Contract x under z = sin(x), over every branch: x = asin(z) + 2*pi*k or
    pi - asin(z) + 2*pi*k."""
    zl, zh = np.maximum(z.lo, -1.0), np.minimum(z.hi, 1.0)
    e = z.is_empty() | (zl > zh)
    zl, zh = np.where(e, -1.0, zl), np.where(e, 1.0, zh)
    b = IV(
        np.maximum(np.arcsin(zl) - TRANS_MARGIN, -HALF_PI.hi),
        np.minimum(np.arcsin(zh) + TRANS_MARGIN, HALF_PI.hi),
    )
    out = meet_angle(x, b) | meet_angle(x, PI - b)
    whole = (zl <= -1.0) & (zh >= 1.0)
    out = IV(np.where(whole, x.lo, out.lo), np.where(whole, x.hi, out.hi))
    return _mask(out, e | x.is_empty())
