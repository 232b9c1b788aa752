"""Guaranteed interval arithmetic on numpy arrays (ekf-vs-cp.txt §2.3, the tool of eq. 5).

An :class:`IV` holds two arrays ``lo`` and ``hi`` of one shape: many intervals at once
(a box is an ``IV`` whose last axis runs over the variables; a batch of boxes adds
leading axes). Every operation broadcasts like numpy and is *guaranteed*: the result
contains every exact result of the operation on points of the operands.

- Rounding is outward: each computed bound is moved one ulp outward with
  ``np.nextafter`` (IEEE arithmetic rounds to nearest, so one step suffices for +, -,
  *, /, sqrt, which are correctly rounded).
- sin, cos, atan2 and acos/asin of libm are not correctly rounded but accurate to a few
  ulp; their bounds are widened by ``TRANS_MARGIN`` (an absolute margin far above that)
  and clipped to their true ranges.
- Empty intervals are ``lo > hi``; the canonical empty is ``[+inf, -inf]``. Every
  operation maps an empty operand to an empty result (no NaN leaks out), so a contractor
  that proves inconsistency simply produces empties.

Angles are plain real intervals (not wrapped); :func:`align_angle` shifts an angle
interval by a multiple of 2*pi next to a reference before intersecting.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * np.pi
# Absolute outward margin for the transcendental functions (libm error is < 4 ulp of 1).
TRANS_MARGIN = 1e-14
_INF = np.inf


def down(a: np.ndarray) -> np.ndarray:
    """Next float towards -inf (outward rounding of a lower bound)."""
    return np.nextafter(a, -_INF)


def up(a: np.ndarray) -> np.ndarray:
    """Next float towards +inf (outward rounding of an upper bound)."""
    return np.nextafter(a, _INF)


def _arr(v) -> np.ndarray:
    return np.asarray(v, dtype=float)


@dataclass(frozen=True, slots=True)
class IV:
    """Intervals ``[lo, hi]`` elementwise; ``lo > hi`` (or NaN) means empty."""

    lo: np.ndarray
    hi: np.ndarray

    # numpy arrays on the left of +, -, * defer to IV's reflected operators.
    __array_ufunc__ = None

    # --- construction -------------------------------------------------------------
    @staticmethod
    def of(lo, hi=None) -> IV:
        """Intervals from bounds (``hi`` defaults to ``lo``: degenerate point intervals)."""
        lo_a = _arr(lo)
        hi_a = lo_a if hi is None else _arr(hi)
        lo_a, hi_a = np.broadcast_arrays(lo_a, hi_a)
        return IV(lo_a.copy(), hi_a.copy())._canon()

    @staticmethod
    def around(mid, rad) -> IV:
        """``[mid - rad, mid + rad]`` rounded outward (rad >= 0)."""
        m, r = _arr(mid), np.abs(_arr(rad))
        return IV(down(m - r), up(m + r))._canon()

    @staticmethod
    def empty(shape=()) -> IV:
        return IV(np.full(shape, _INF), np.full(shape, -_INF))

    @staticmethod
    def entire(shape=()) -> IV:
        return IV(np.full(shape, -_INF), np.full(shape, _INF))

    def _canon(self) -> IV:
        """Canonical empties: any lo > hi or NaN becomes [+inf, -inf]."""
        bad = ~(self.lo <= self.hi)
        if bad.any():
            lo = np.where(bad, _INF, self.lo)
            hi = np.where(bad, -_INF, self.hi)
            return IV(lo, hi)
        return self

    # --- queries ------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, ...]:
        return np.shape(self.lo)

    def is_empty(self) -> np.ndarray:
        return ~(self.lo <= self.hi)

    def width(self) -> np.ndarray:
        """hi - lo (0 for empties), rounded up."""
        return np.where(self.is_empty(), 0.0, up(self.hi - self.lo))

    def mid(self) -> np.ndarray:
        """Midpoint (0 for the entire line and for empties)."""
        with np.errstate(invalid="ignore"):
            m = 0.5 * self.lo + 0.5 * self.hi
        return np.where(np.isnan(m), 0.0, m)

    def mag(self) -> np.ndarray:
        """max |x| over the interval."""
        return np.maximum(np.abs(self.lo), np.abs(self.hi))

    def contains(self, v) -> np.ndarray:
        v = _arr(v)
        return (self.lo <= v) & (v <= self.hi)

    def subset_of(self, other: IV) -> np.ndarray:
        return self.is_empty() | ((other.lo <= self.lo) & (self.hi <= other.hi))

    def __getitem__(self, idx) -> IV:
        return IV(self.lo[idx], self.hi[idx])

    # --- lattice ------------------------------------------------------------------
    def __and__(self, other: IV) -> IV:
        """Intersection."""
        other = as_iv(other)
        return IV(np.maximum(self.lo, other.lo), np.minimum(self.hi, other.hi))._canon()

    def __or__(self, other: IV) -> IV:
        """Hull of the union (empties are neutral)."""
        other = as_iv(other)
        return IV(np.minimum(self.lo, other.lo), np.maximum(self.hi, other.hi))._canon()

    def inflate(self, r) -> IV:
        """Widened by ``r >= 0`` on both sides (empties stay empty)."""
        r = np.abs(_arr(r))
        return IV(np.where(self.is_empty(), _INF, down(self.lo - r)), up(self.hi + r))._canon()

    # --- arithmetic ---------------------------------------------------------------
    def __neg__(self) -> IV:
        return IV(-self.hi, -self.lo)._canon()

    def __add__(self, other) -> IV:
        o = as_iv(other)
        e = self.is_empty() | o.is_empty()
        return _mask(IV(down(self.lo + o.lo), up(self.hi + o.hi)), e)

    __radd__ = __add__

    def __sub__(self, other) -> IV:
        o = as_iv(other)
        e = self.is_empty() | o.is_empty()
        return _mask(IV(down(self.lo - o.hi), up(self.hi - o.lo)), e)

    def __rsub__(self, other) -> IV:
        return as_iv(other) - self

    def __mul__(self, other) -> IV:
        o = as_iv(other)
        e = self.is_empty() | o.is_empty()
        with np.errstate(invalid="ignore", over="ignore"):
            p1, p2 = self.lo * o.lo, self.lo * o.hi
            p3, p4 = self.hi * o.lo, self.hi * o.hi
            lo = np.minimum(np.minimum(p1, p2), np.minimum(p3, p4))
            hi = np.maximum(np.maximum(p1, p2), np.maximum(p3, p4))
        if np.isnan(lo).any() or np.isnan(hi).any():
            # 0 * inf: that product's bound is unbounded (a guaranteed answer).
            lo = np.fmin(
                np.fmin(_nan_to(p1, -_INF), _nan_to(p2, -_INF)),
                np.fmin(_nan_to(p3, -_INF), _nan_to(p4, -_INF)),
            )
            hi = np.fmax(
                np.fmax(_nan_to(p1, _INF), _nan_to(p2, _INF)),
                np.fmax(_nan_to(p3, _INF), _nan_to(p4, _INF)),
            )
        return _mask(IV(down(lo), up(hi)), e)

    __rmul__ = __mul__

    def __truediv__(self, other) -> IV:
        o = as_iv(other)
        return self * o.reciprocal()

    def __rtruediv__(self, other) -> IV:
        return as_iv(other) * self.reciprocal()

    def reciprocal(self) -> IV:
        """1/x: [1/hi, 1/lo] off zero; a half-line if 0 is an end; entire if 0 is inside."""
        lo_x, hi_x = np.broadcast_arrays(self.lo, self.hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            r_hi = 1.0 / hi_x
            r_lo = 1.0 / lo_x
        lo = down(r_hi)
        hi = up(r_lo)
        inside = (lo_x < 0.0) & (hi_x > 0.0)
        lo = np.where(inside | ((hi_x == 0.0) & (lo_x < 0.0)), -_INF, lo)
        hi = np.where(inside | ((lo_x == 0.0) & (hi_x > 0.0)), _INF, hi)
        both0 = (lo_x == 0.0) & (hi_x == 0.0)
        return _mask(IV(lo, hi), self.is_empty() | both0)

    def scale(self, k) -> IV:
        """Multiplication by exact real scalars/arrays ``k``."""
        return self * IV.of(k)


def _nan_to(a: np.ndarray, v: float) -> np.ndarray:
    return np.where(np.isnan(a), v, a)


def as_iv(v) -> IV:
    return v if isinstance(v, IV) else IV.of(v)


def _mask(iv: IV, empty: np.ndarray) -> IV:
    """Force ``empty`` positions to the canonical empty."""
    if np.asarray(empty).any():
        return IV(np.where(empty, _INF, iv.lo), np.where(empty, -_INF, iv.hi))._canon()
    return iv._canon()


# --- elementary functions ---------------------------------------------------------
def sqr(x: IV) -> IV:
    """x**2 (tighter than x*x: the result is non-negative)."""
    a, b = x.lo * x.lo, x.hi * x.hi
    zero_in = (x.lo <= 0.0) & (x.hi >= 0.0)
    lo = np.where(zero_in, 0.0, down(np.minimum(a, b)))
    hi = up(np.maximum(a, b))
    return _mask(IV(np.maximum(lo, 0.0), hi), x.is_empty())


def sqrt(x: IV) -> IV:
    """sqrt of the non-negative part of x (empty if x < 0 entirely)."""
    e = x.is_empty() | (x.hi < 0.0)
    lo = np.maximum(x.lo, 0.0)
    hi = np.maximum(x.hi, 0.0)
    return _mask(IV(np.maximum(down(np.sqrt(lo)), 0.0), up(np.sqrt(hi))), e)


def _trans(lo: np.ndarray, hi: np.ndarray, floor: float, ceil: float) -> tuple:
    return (
        np.maximum(lo - TRANS_MARGIN, floor),
        np.minimum(hi + TRANS_MARGIN, ceil),
    )


def cos(x: IV) -> IV:
    """cos over x: the bounds at the ends and every extremum (k*pi) inside."""
    e = x.is_empty() | ~np.isfinite(x.lo) | ~np.isfinite(x.hi)
    lo_x = np.where(e, 0.0, x.lo)
    hi_x = np.where(e, 0.0, x.hi)
    c1, c2 = np.cos(lo_x), np.cos(hi_x)
    lo = np.minimum(c1, c2)
    hi = np.maximum(c1, c2)
    # Conservative extremum tests: widen the argument slightly so a maximum at 2k*pi
    # or minimum at (2k+1)*pi that is merely *near* an end is included (safe).
    slack = 1e-12 * (1.0 + np.abs(lo_x) + np.abs(hi_x))
    k_max = np.ceil((lo_x - slack) / TWO_PI)
    has_max = k_max * TWO_PI <= hi_x + slack
    k_min = np.ceil((lo_x - slack - np.pi) / TWO_PI)
    has_min = k_min * TWO_PI + np.pi <= hi_x + slack
    hi = np.where(has_max, 1.0, hi)
    lo = np.where(has_min, -1.0, lo)
    wide = (hi_x - lo_x) >= TWO_PI
    lo = np.where(wide, -1.0, lo)
    hi = np.where(wide, 1.0, hi)
    lo, hi = _trans(lo, hi, -1.0, 1.0)
    out = IV(lo, hi)
    # Unbounded (non-empty) arguments give [-1, 1].
    unb = ~x.is_empty() & (~np.isfinite(x.lo) | ~np.isfinite(x.hi))
    out = IV(np.where(unb, -1.0, out.lo), np.where(unb, 1.0, out.hi))
    return _mask(out, x.is_empty())


def sin(x: IV) -> IV:
    """sin(x) = cos(x - pi/2), with the shift rounded outward."""
    half_pi = IV(np.array(down(np.pi / 2)), np.array(up(np.pi / 2)))
    return cos(x - half_pi)


def atan2(y: IV, x: IV, ref=None) -> IV:
    """The angles of every point of the box ``y x x`` (bearing of (x, y)), as a real
    interval near ``ref`` (default: the bearing of the box centre).

    A box containing the origin gives ``ref + [-pi, pi]``; otherwise the angle span is
    below pi and is found from the four corners relative to ``ref``.
    """
    e = y.is_empty() | x.is_empty()
    yl, yh = np.broadcast_arrays(y.lo, y.hi)
    xl, xh = np.broadcast_arrays(x.lo, x.hi)
    fin = np.isfinite(yl) & np.isfinite(yh) & np.isfinite(xl) & np.isfinite(xh) & ~e
    yl, yh = np.where(fin, yl, 0.0), np.where(fin, yh, 0.0)
    xl, xh = np.where(fin, xl, 1.0), np.where(fin, xh, 1.0)
    if ref is None:
        ref = np.arctan2(0.5 * yl + 0.5 * yh, 0.5 * xl + 0.5 * xh)
    ref = np.broadcast_to(_arr(ref), np.shape(yl))
    corners = np.stack([np.arctan2(yy, xx) for yy in (yl, yh) for xx in (xl, xh)])
    d = np.remainder(corners - ref + np.pi, TWO_PI) - np.pi
    lo = ref + d.min(axis=0)
    hi = ref + d.max(axis=0)
    # The extreme bearing of a box is always at a corner unless the box straddles an
    # axis on the far side; corners cover that too as long as the origin is outside.
    origin_in = (xl <= 0.0) & (xh >= 0.0) & (yl <= 0.0) & (yh >= 0.0)
    lo = np.where(origin_in | ~fin, ref - np.pi, lo)
    hi = np.where(origin_in | ~fin, ref + np.pi, hi)
    margin = TRANS_MARGIN * (1.0 + np.abs(ref)) + 4e-16 * TWO_PI
    return _mask(IV(down(lo - margin), up(hi + margin)), e)


def align_angle(a: IV, ref) -> IV:
    """``a`` shifted by the multiple of 2*pi that brings its centre closest to ``ref``."""
    k = np.round((_arr(ref) - a.mid()) / TWO_PI)
    k = np.where(np.isfinite(k), k, 0.0)
    shift = IV(down(k * TWO_PI), up(k * TWO_PI))
    return a + shift


def sinc_half(d: IV) -> IV:
    """sin(d/2)/(d/2): the chord-to-arc ratio of a turn by ``d``; within
    [1 - m^2/24, 1] for |d| <= m (alternating series), exactly 1 at d = 0."""
    m = d.mag()
    lo = down(1.0 - up(m * m) / 24.0)
    return _mask(IV(np.maximum(lo, 0.0), np.ones_like(lo)), d.is_empty())


# --- inverse (backward) projections used by the HC4 contractors ----------------------
def bwd_sqr(z: IV, x: IV) -> IV:
    """Contract x under z = x**2: x ∩ hull((-sqrt z) ∪ (sqrt z))."""
    r = sqrt(z)
    pos = x & r
    neg = x & (-r)
    return pos | neg


def bwd_mul(z: IV, x: IV, y: IV) -> IV:
    """Contract x under z = x * y (only where 0 is not in y; otherwise x unchanged)."""
    zero_in = (y.lo <= 0.0) & (y.hi >= 0.0)
    q = z / IV(np.where(zero_in, 1.0, y.lo), np.where(zero_in, 1.0, y.hi))
    q = IV(np.where(zero_in, -_INF, q.lo), np.where(zero_in, _INF, q.hi))
    return x & q


def bwd_cos(z: IV, x: IV) -> IV:
    """Contract x under z = cos(x), only where x lies on one monotone branch of cos.

    On [k*pi, (k+1)*pi] cos is monotone, and x = 2*pi*m +/- acos(z). Elsewhere x is
    returned unchanged (guaranteed, if not optimal).
    """
    k = np.floor(x.lo / np.pi)
    k = np.where(np.isfinite(k), k, 0.0)
    one_branch = (x.hi <= (k + 1.0) * np.pi - 1e-12 * (1.0 + np.abs(x.hi))) & np.isfinite(x.hi)
    zc = IV(np.clip(z.lo, -1.0, 1.0), np.clip(z.hi, -1.0, 1.0))
    a_lo = np.arccos(zc.hi) - TRANS_MARGIN  # acos is decreasing
    a_hi = np.arccos(zc.lo) + TRANS_MARGIN
    m = np.floor(k / 2.0)
    base = m * TWO_PI
    even = np.remainder(k, 2.0) == 0.0  # branch [2m*pi, (2m+1)*pi]: x = base + acos
    lo = np.where(even, base + a_lo, base + TWO_PI - a_hi)
    hi = np.where(even, base + a_hi, base + TWO_PI - a_lo)
    slack = 1e-12 * (1.0 + np.abs(base))
    cand = IV(down(lo - slack), up(hi + slack))
    cand = IV(np.where(one_branch, cand.lo, -_INF), np.where(one_branch, cand.hi, _INF))
    return _mask(x & cand, z.is_empty() | (z.lo > 1.0) | (z.hi < -1.0))


def bwd_sin(z: IV, x: IV) -> IV:
    """Contract x under z = sin(x) = cos(x - pi/2)."""
    half_pi = IV(np.array(down(np.pi / 2)), np.array(up(np.pi / 2)))
    return x & (bwd_cos(z, x - half_pi) + half_pi)
