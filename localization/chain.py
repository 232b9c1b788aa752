"""Exact forward-backward contraction of a linear chain ``v[k+1] = v[k] + d[k]`` over a
sliding window (the additive part of eq. (2) of ekf-vs-cp.txt, for x, y and theta).

Given measurement intervals ``m[k]`` of every state of the window and increment
intervals ``d[k]``, the smallest boxes consistent with all of them are

    v[k] = ∩_j ( m[j] + sum_{i=j}^{k-1} d[i] )      (sums taken backwards for j > k)

which is the fixpoint that repeated forward and backward HC4 sweeps converge to; here it
is computed in one shot from prefix sums with running maxima/minima (O(n), vectorised).
:func:`relaxed_chain` is the q-relaxed intersection: every point consistent with all but
at most ``q`` of the relaxable measurements (outliers such as a GPS jump), whose hull is
bounded by the (q+1)-th largest lower and (q+1)-th smallest upper bound.

Guarantee under floating point: the prefix sums carry at most ``n * eps * sum|d|`` of
rounding error (recursive summation bound); every result is widened by four times that
bound plus one ulp outward.
"""

from __future__ import annotations

import numpy as np

from localization.interval import IV, down, up

_EPS = np.finfo(float).eps


def _prefix(d: IV) -> tuple[np.ndarray, np.ndarray, float]:
    s_lo = np.concatenate([[0.0], np.cumsum(d.lo)])
    s_hi = np.concatenate([[0.0], np.cumsum(d.hi)])
    mag = float(np.sum(np.abs(d.lo)) + np.sum(np.abs(d.hi)))
    return s_lo, s_hi, mag


def _guard(n: int, mag: float, m: IV) -> float:
    fin = np.concatenate([m.lo[np.isfinite(m.lo)], m.hi[np.isfinite(m.hi)]])
    big = float(np.max(np.abs(fin), initial=0.0))
    return 4.0 * (n + 4) * _EPS * (mag + big) + 1e-300


def chain(m: IV, d: IV) -> IV:
    """Contract the window ``m`` (shape (n,)) by the increments ``d`` (shape (n-1,))."""
    n = m.lo.shape[0]
    if n == 0:
        return m
    if np.any(d.is_empty()):
        return IV.empty((n,))
    s_lo, s_hi, mag = _prefix(d)
    g = _guard(n, mag, m)
    with np.errstate(invalid="ignore"):
        f_lo = s_lo + np.maximum.accumulate(m.lo - s_lo)
        f_hi = s_hi + np.minimum.accumulate(m.hi - s_hi)
        b_lo = s_hi + np.maximum.accumulate((m.lo - s_hi)[::-1])[::-1]
        b_hi = s_lo + np.minimum.accumulate((m.hi - s_lo)[::-1])[::-1]
    lo = np.maximum(f_lo, b_lo)
    hi = np.minimum(f_hi, b_hi)
    lo = np.where(np.isnan(lo), -np.inf, lo)
    hi = np.where(np.isnan(hi), np.inf, hi)
    out = IV(down(lo - g), up(hi + g))
    return out & m


def relaxed_chain(m: IV, valid: np.ndarray, d: IV, q: int) -> tuple[IV, np.ndarray]:
    """q-relaxed chain: boxes of every state consistent with the increments and with all
    but at most ``q`` of the measurements ``m[j]`` where ``valid[j]``.

    Returns (boxes (n,), consistent (n,) bool: measurement j meets its box's hull).
    With q = 0 this equals :func:`chain` restricted to the valid measurements.
    """
    n = m.lo.shape[0]
    valid = np.asarray(valid, dtype=bool)
    idx = np.flatnonzero(valid)
    nv = idx.size
    if nv <= q or np.any(d.is_empty()):
        return IV.entire((n,)) if nv <= q else IV.empty((n,)), valid.copy()
    s_lo, s_hi, mag = _prefix(d)
    g = _guard(n, mag, m)
    k = np.arange(n)[None, :]
    j = idx[:, None]
    mlo, mhi = m.lo[idx][:, None], m.hi[idx][:, None]
    fwd = j <= k
    lo_jk = np.where(fwd, mlo + (s_lo[k] - s_lo[j]), mlo - (s_hi[j] - s_hi[k]))
    hi_jk = np.where(fwd, mhi + (s_hi[k] - s_hi[j]), mhi - (s_lo[j] - s_lo[k]))
    lo = np.sort(lo_jk, axis=0)[nv - 1 - q]  # (q+1)-th largest lower bound
    hi = np.sort(hi_jk, axis=0)[q]  # (q+1)-th smallest upper bound
    out = IV(down(lo - g), up(hi + g))
    consistent = valid & (m.lo <= out.hi) & (m.hi >= out.lo)
    return out, consistent
