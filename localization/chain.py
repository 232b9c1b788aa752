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
:func:`relaxed_chain_at` is the same for any number of relaxable measurements per state
(``at[j]`` is measurement j's state), on bare arrays, with hard (never relaxed) boxes
per state: the form the real-robot window solver (``localization.cp_rb_solve``) uses for
x, y and the heading offset.

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
    lo, hi = chain_k(m.lo, m.hi, d.lo, d.hi)
    return IV(lo, hi) & m


def _prefix_k(dl: np.ndarray, dh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    z = np.zeros(dl.shape[:-1] + (1,))
    return (
        np.concatenate([z, np.cumsum(dl, axis=-1)], axis=-1),
        np.concatenate([z, np.cumsum(dh, axis=-1)], axis=-1),
    )


def chain_k(
    ml: np.ndarray, mh: np.ndarray, dl: np.ndarray, dh: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`chain` on bare arrays, along the last axis (``m`` (..., n) non-empty or
    empty, ``d`` (..., n-1) non-empty, broadcast): the contracted bounds, not yet met
    with ``m``."""
    n = ml.shape[-1]
    s_lo, s_hi = _prefix_k(dl, dh)
    with np.errstate(invalid="ignore"):
        f_lo = s_lo + np.maximum.accumulate(ml - s_lo, axis=-1)
        f_hi = s_hi + np.minimum.accumulate(mh - s_hi, axis=-1)
        b_lo = s_hi + np.maximum.accumulate((ml - s_hi)[..., ::-1], axis=-1)[..., ::-1]
        b_hi = s_lo + np.minimum.accumulate((mh - s_lo)[..., ::-1], axis=-1)[..., ::-1]
    lo = np.maximum(f_lo, b_lo)
    hi = np.minimum(f_hi, b_hi)
    lo = np.where(np.isnan(lo), -np.inf, lo)
    hi = np.where(np.isnan(hi), np.inf, hi)
    return _widen_k(lo, hi, n, dl, dh)


def _widen_k(lo: np.ndarray, hi: np.ndarray, n: int, dl, dh) -> tuple[np.ndarray, np.ndarray]:
    """Bounds widened by the prefix sums' rounding error (module doc): each bound is one
    measurement plus or minus a sum of at most n increments, so its error is below
    (n + 4) eps (2 sum|d| + |bound|); taken four times, which also covers the rounding
    of the widening itself."""
    mag = float(np.max(np.sum(np.abs(dl) + np.abs(dh), axis=-1), initial=0.0))
    k = 4.0 * (n + 4) * _EPS
    g = k * 2.0 * mag + 1e-300
    with np.errstate(invalid="ignore", over="ignore"):
        return lo - (g + k * np.abs(lo)), hi + (g + k * np.abs(hi))


def relaxed_chain_at(
    hard: tuple[np.ndarray, np.ndarray],
    meas: tuple[np.ndarray, np.ndarray],
    at: np.ndarray,
    d: tuple[np.ndarray, np.ndarray],
    q: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (..., n) of a chain ``v[k+1] = v[k] + d[k]`` consistent with every hard box
    ``hard`` (..., n) and with all but at most ``q`` of the measurements ``meas``
    (..., m) of states ``at`` (m,). An empty measurement (lo > hi) is one the caller
    has already proven wrong: it counts as one of the q. Bare arrays, leading axes
    broadcast (a batch of windows); ``d`` (..., n-1) finite and non-empty. Returns
    (lo, hi), empty (lo > hi) where nothing is consistent."""
    hl, hh = hard
    dl, dh = d
    m = at.shape[0]
    lo, hi = chain_k(hl, hh, dl, dh)
    lo, hi = np.maximum(lo, hl), np.minimum(hi, hh)
    if m <= q:
        return lo, hi
    p_lo, p_hi = projections(meas, at, d)  # rounded outward; empties stay empty
    r_lo = np.partition(p_lo, m - 1 - q, axis=-2)[..., m - 1 - q, :]  # (q+1)-th largest lo
    r_hi = np.partition(p_hi, q, axis=-2)[..., q, :]  # (q+1)-th smallest upper bound
    return np.maximum(lo, r_lo), np.minimum(hi, r_hi)


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


def projections(
    meas: tuple[np.ndarray, np.ndarray], at: np.ndarray, d: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """Every measurement (..., m) of state ``at`` (m,) carried along the chain ``d``
    (..., n-1) to every state: (lo, hi) of shape (..., m, n), rounded outward (empty
    measurements stay empty)."""
    ml, mh = meas
    dl, dh = d
    n = dl.shape[-1] + 1
    s_lo, s_hi = _prefix_k(dl, dh)
    fwd = np.arange(n)[None, :] >= at[:, None]  # (m, n)
    sj_lo, sj_hi = s_lo[..., at][..., :, None], s_hi[..., at][..., :, None]
    sk_lo, sk_hi = s_lo[..., None, :], s_hi[..., None, :]
    with np.errstate(invalid="ignore"):
        p_lo = ml[..., :, None] + np.where(fwd, sk_lo - sj_lo, sk_hi - sj_hi)
        p_hi = mh[..., :, None] + np.where(fwd, sk_hi - sj_hi, sk_lo - sj_lo)
    empty = np.isnan(p_lo) | np.isnan(p_hi) | ~(ml <= mh)[..., :, None]
    p_lo, p_hi = _widen_k(p_lo, p_hi, n, dl, dh)
    return np.where(empty, np.inf, p_lo), np.where(empty, -np.inf, p_hi)


def leave_out(p: np.ndarray, q: int, hyps: np.ndarray, largest: bool) -> np.ndarray:
    """For every hypothesis h (a row of ``hyps`` (H, q): the indices of the q
    measurements it leaves out), the largest (``largest``) or smallest of ``p``
    (..., m, n) over the measurements it keeps: (..., H, n). Built from the q + 1
    extreme values per state (their indices decide which one a hypothesis keeps), so the
    cost grows with H n, not H m n."""
    m = p.shape[-2]
    fill = -np.inf if largest else np.inf
    work = p
    vals, idxs = [], []
    rows = np.arange(m)[:, None]
    for r in range(min(q + 1, m)):
        a = np.argmax(work, axis=-2) if largest else np.argmin(work, axis=-2)  # (..., n)
        hit = rows == a[..., None, :]  # (..., m, n)
        vals.append(np.max(work, axis=-2) if largest else np.min(work, axis=-2))
        idxs.append(a)
        if r < q:
            work = np.where(hit, fill, work)
    if q == 1 and hyps.shape[0] == m and m > 1:  # the usual case: leave each one out
        return np.where(rows == idxs[0][..., None, :], vals[1][..., None, :], vals[0][..., None, :])
    out = np.full(p.shape[:-2] + (hyps.shape[0], p.shape[-1]), fill)
    for v, a in zip(vals[::-1], idxs[::-1], strict=True):
        gone = np.zeros(out.shape, bool)
        for col in range(hyps.shape[1]):
            gone |= a[..., None, :] == hyps[:, col][:, None]
        out = np.where(gone, out, v[..., None, :])
    return out
