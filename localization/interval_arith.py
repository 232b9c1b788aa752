"""Guaranteed interval arithmetic on numpy arrays (ekf-vs-cp.txt §2.3: the tool that
solves the constraint problem H of eq. (5) for the model eq. (1)-(2)).

An :class:`IV` holds two arrays ``lo`` and ``hi`` of one shape: many intervals at once
(a box is an ``IV`` whose last axis runs over the variables; a batch of boxes adds
leading axes). Every operation broadcasts like numpy and is *guaranteed*: the result
contains every exact result of the operation on real points of the operands.

- Rounding is outward: each computed bound is moved one ulp outward with
  ``np.nextafter`` (IEEE arithmetic rounds to nearest, so one step suffices for +, -,
  *, /, sqrt, which are correctly rounded; also for overflow to +-inf and for underflow
  into the denormals, whose spacing is uniform).
- Intervals are sets of reals: unbounded ends are +-inf, never attained. Empty
  intervals are ``lo > hi`` (or NaN); the canonical empty is ``[+inf, -inf]``.
  :meth:`IV.of` also maps ``[+inf, +inf]`` and ``[-inf, -inf]`` (no real inside) to it;
  no operation produces them (rounded bounds stop at the largest finite float). Every operation maps an empty
  operand to an empty result (no NaN leaks out), so a contractor that proves
  inconsistency simply produces empties.
- ``0 * inf`` at a bound is 0 (the product of the real 0 with any real is 0), so
  ``[0, 0] * [1, inf] = [0, 0]``.

Here: the class, + - * /, ``sqr``, ``sqrt`` and the backward (projection) operators of
the polynomial parts. The periodic functions and angle intervals are in
``localization.interval_trig``; ``localization.interval`` gathers both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
        if hi is None:  # point intervals: a real, not +-inf or NaN
            p = np.array(lo, dtype=float)
            bad = ~np.isfinite(p)
            if bad.any():
                return IV(np.where(bad, _INF, p), np.where(bad, -_INF, p))
            return IV(p, p)
        lo_a, hi_a = np.broadcast_arrays(_arr(lo), _arr(hi))
        # [inf, inf] and [-inf, -inf] hold no real: empty (no operation makes them).
        bad = ~(lo_a <= hi_a) | (lo_a == _INF) | (hi_a == -_INF)
        if bad.any():
            return IV(np.where(bad, _INF, lo_a), np.where(bad, -_INF, hi_a))
        return IV(lo_a.copy(), hi_a.copy())

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
        with np.errstate(invalid="ignore"):
            return np.where(self.is_empty(), 0.0, up(self.hi - self.lo))

    def mid(self) -> np.ndarray:
        """Midpoint (0 for the entire line and for empties; a half-line gives its end)."""
        with np.errstate(invalid="ignore"):
            m = 0.5 * self.lo + 0.5 * self.hi
        if np.isfinite(m).all():
            return m
        m = np.where(np.isnan(m), 0.0, m)
        m = np.where(np.isneginf(m) & np.isfinite(self.hi), self.hi, m)
        return np.where(np.isposinf(m) & np.isfinite(self.lo), self.lo, m)

    def mag(self) -> np.ndarray:
        """max |x| over the interval."""
        return np.maximum(np.abs(self.lo), np.abs(self.hi))

    def mig(self) -> np.ndarray:
        """min |x| over the interval (0 if it holds 0)."""
        zero_in = (self.lo <= 0.0) & (self.hi >= 0.0)
        return np.where(zero_in, 0.0, np.minimum(np.abs(self.lo), np.abs(self.hi)))

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
        a, b = self._canon(), other._canon()
        return IV(np.minimum(a.lo, b.lo), np.maximum(a.hi, b.hi))._canon()

    def inflate(self, r) -> IV:
        """Widened by ``r >= 0`` on both sides (empties stay empty)."""
        r = np.abs(_arr(r))
        return _mask(IV(down(self.lo - r), up(self.hi + r)), self.is_empty())

    # --- arithmetic ---------------------------------------------------------------
    def __neg__(self) -> IV:
        return IV(-self.hi, -self.lo)._canon()

    def __add__(self, other) -> IV:
        o = as_iv(other)
        e = self.is_empty() | o.is_empty()
        if not e.any():  # no inf - inf, and lo <= hi: already canonical
            return IV(down(self.lo + o.lo), up(self.hi + o.hi))
        with np.errstate(invalid="ignore"):
            return _mask(IV(down(self.lo + o.lo), up(self.hi + o.hi)), e)

    __radd__ = __add__

    def __sub__(self, other) -> IV:
        o = as_iv(other)
        e = self.is_empty() | o.is_empty()
        if not e.any():
            return IV(down(self.lo - o.hi), up(self.hi - o.lo))
        with np.errstate(invalid="ignore"):
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
            # 0 * inf (a real 0 bound times an unbounded end) contributes 0.
            p1, p2, p3, p4 = (_nan_to(p, 0.0) for p in (p1, p2, p3, p4))
            lo = np.minimum(np.minimum(p1, p2), np.minimum(p3, p4))
            hi = np.maximum(np.maximum(p1, p2), np.maximum(p3, p4))
        if not e.any():
            return IV(down(lo), up(hi))
        return _mask(IV(down(lo), up(hi)), e)

    __rmul__ = __mul__

    def __truediv__(self, other) -> IV:
        return _div(self, as_iv(other))

    def __rtruediv__(self, other) -> IV:
        return _div(as_iv(other), self)

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


def _div(x: IV, y: IV) -> IV:
    """x / y over the reals y != 0: the four end quotients (0/0 and inf/inf, which only
    occur where other quotients bound the result, are left out) when 0 is not inside y,
    the entire line when it is (x = [0, 0] excepted), empty for y = [0, 0]."""
    xl, xh, yl, yh = np.broadcast_arrays(x.lo, x.hi, y.lo, y.hi)
    yl = np.where(yl == 0.0, 0.0, yl)  # +0: x / +0 is +-inf with the sign of x
    yh = np.where(yh == 0.0, -0.0, yh)  # -0: x / -0 is -+inf
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        q1, q2, q3, q4 = xl / yl, xl / yh, xh / yl, xh / yh
        # fmin/fmax skip the NaN quotients (all four are NaN only where x = [0, 0] or
        # y = [0, 0], both handled below)
        lo = np.fmin(np.fmin(q1, q2), np.fmin(q3, q4))
        hi = np.fmax(np.fmax(q1, q2), np.fmax(q3, q4))
    zero_x = (xl == 0.0) & (xh == 0.0)
    inside = (yl < 0.0) & (yh > 0.0) & ~zero_x
    lo = np.where(inside, -_INF, np.where(zero_x, 0.0, down(lo)))
    hi = np.where(inside, _INF, np.where(zero_x, 0.0, up(hi)))
    e = x.is_empty() | y.is_empty() | ((yl == 0.0) & (yh == 0.0))
    return _mask(IV(lo, hi), np.broadcast_to(e, lo.shape))


# --- elementary functions ---------------------------------------------------------
def sqr(x: IV) -> IV:
    """x**2 (tighter than x*x: the result is non-negative)."""
    with np.errstate(over="ignore"):
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


# --- inverse (backward) projections used by the HC4 contractors ----------------------
def bwd_sqr(z: IV, x: IV) -> IV:
    """Contract x under z = x**2: x ∩ hull((-sqrt z) ∪ (sqrt z))."""
    r = sqrt(z)
    pos = x & r
    neg = x & (-r)
    return pos | neg


def bwd_mul(z: IV, x: IV, y: IV) -> IV:
    """Contract x under z = x * y: x ∩ hull({z / y}) with the division extended over a
    y holding 0 (two half-lines when 0 is not in z; x unchanged when it is)."""
    zl, zh, yl, yh = np.broadcast_arrays(z.lo, z.hi, y.lo, y.hi)
    y0 = (yl <= 0.0) & (yh >= 0.0)
    z0 = (zl <= 0.0) & (zh >= 0.0)
    plain = x & (z / y)  # exact where 0 is not in y
    # 0 in y, z > 0 or z < 0: x = z / y lies in (-inf, a] ∪ [b, +inf).
    zpos = zl > 0.0
    num = np.where(zpos, zl, zh)  # the end of z nearest to 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        q_lo_y = num / np.where(yl < 0.0, yl, -_INF)  # z / (negative part of y)
        q_hi_y = num / np.where(yh > 0.0, yh, _INF)  # z / (positive part of y)
    q_lo_y, q_hi_y = _nan_to(q_lo_y, 0.0), _nan_to(q_hi_y, 0.0)
    # z > 0: x <= num/yl (y < 0) or x >= num/yh (y > 0); z < 0: mirrored.
    left_end = np.where(zpos, q_lo_y, q_hi_y)
    right_end = np.where(zpos, q_hi_y, q_lo_y)
    left_ok = np.where(zpos, yl < 0.0, yh > 0.0)
    right_ok = np.where(zpos, yh > 0.0, yl < 0.0)
    # (an absent half-line is the canonical empty [inf, -inf])
    left = IV(np.where(left_ok, -_INF, _INF), np.where(left_ok, up(left_end), -_INF))
    right = IV(np.where(right_ok, down(right_end), _INF), np.where(right_ok, _INF, -_INF))
    split = (x & left) | (x & right)
    out_lo = np.where(y0 & z0, x.lo, np.where(y0, split.lo, plain.lo))
    out_hi = np.where(y0 & z0, x.hi, np.where(y0, split.hi, plain.hi))
    e = z.is_empty() | y.is_empty()
    return _mask(IV(out_lo, out_hi), np.broadcast_to(e, np.shape(out_lo)) | x.is_empty())
