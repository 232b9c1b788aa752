"""Covariance intersection (CI) of a prior with a measurement whose error may be
correlated with the prior in an unknown way (Julier & Uhlmann, "A non-divergent
estimation algorithm in the presence of unknown correlations", ACC 1997).

With prior (x, P) and a measurement z = h(x) + e, Jacobian H (m x n) and noise R
(which here holds the peer robot's covariance as well), CI fuses the informations
with weights w and 1 - w:

    P+^-1 = w P^-1 + (1 - w) H^T R^-1 H,                                  (CI)

which is the Kalman update with the prior covariance P / w and the noise R / (1 - w)
(the same algebra as numerics.ekf, so the Joseph form applies). The result is
consistent whatever the correlation between the two, for every w in (0, 1]. w = 1
ignores the measurement.

Choice of w: minimise det P+ (default) or trace P+.

- det: with A = H P H^T and lambda_k the eigenvalues of R^-1 A (k = 1..m), Sylvester's
  determinant identity gives det P+^-1 = det P^-1 w^(n-m) prod_k (lambda_k + w (1 -
  lambda_k)), log-concave in w. Its derivative vanishes at
  (n - m) / w + sum_k (1 - lambda_k) / (lambda_k + w (1 - lambda_k)) = 0,
  found by bisection; the optimum is w = 1 (no update) when sum_k lambda_k <= n, i.e.
  when the measurement carries too little information to beat the prior alone.
- trace: golden-section search of trace P+(w) on [1e-3, 1]; so is either criterion
  judged on a leading block of P+ only (the pose, without nuisance states).

Split covariance intersection (SCI; Julier & Uhlmann, "General decentralized data fusion
with covariance intersection", Handbook of Multisensor Data Fusion, 2001; Li &
Nashashibi, "Cooperative multi-vehicle localization using split covariance intersection
filter", IEEE ITS Magazine 2013): the measurement error is e_d + e_i, e_d of unknown
correlation with the prior error (covariance at most R_d: e.g. a peer's estimate) and
e_i independent of both (R_i: the camera noise of this measurement). Then

    P1 = P / w,    R2 = R_d / (1 - w) + R_i,    the Kalman update with (P1, R2)    (SCI)

is consistent for every w in (0, 1]: the error after the update is
(I - K H) e_x - K e_d - K e_i, and cov(a + b) <= cov(a) / w + cov(b) / (1 - w) for any
correlation of a = (I - K H) e_x and b = -K e_d, while K e_i adds K R_i K^T; the Joseph
form with (P1, R2) is exactly that bound. R_i = 0 is CI. Its weight minimises the
criterion on the pose block over a grid of w refined twice (the criterion need not be
unimodal in w); w = 1 (no update) when no w < 1 beats it.
"""

from __future__ import annotations

import math

import numpy as np

from numerics import ekf


def ci_weight(
    p: np.ndarray, h: np.ndarray, r: np.ndarray, criterion: str = "det", block: int | None = None
) -> float:
    """The CI weight w in (0, 1] of the prior ``p`` (1: the measurement adds nothing).

    ``block``: judge the criterion on the leading block P+[:block, :block] only (e.g. the
    pose of a state that also holds nuisance biases), by golden-section search.
    """
    if criterion not in ("det", "trace"):
        raise ValueError(f"criterion must be 'det' or 'trace', got {criterion!r}")
    if block is not None and block < p.shape[0]:
        measure = np.linalg.det if criterion == "det" else np.trace
        return _golden(lambda w: float(measure(ci_posterior(p, h, r, w)[:block, :block])))
    if criterion == "trace":
        return _golden(lambda w: float(np.trace(ci_posterior(p, h, r, w))))
    n, m = p.shape[0], h.shape[0]
    lam = np.maximum(np.linalg.eigvals(np.linalg.solve(r, h @ p @ h.T)).real, 0.0)
    if lam.sum() <= n:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(60):
        w = 0.5 * (lo + hi)
        g = (n - m) / w + sum((1.0 - lk) / (lk + w * (1.0 - lk)) for lk in lam)
        lo, hi = (w, hi) if g > 0.0 else (lo, w)
    return 0.5 * (lo + hi)


def ci_posterior(p: np.ndarray, h: np.ndarray, r: np.ndarray, w: float) -> np.ndarray:
    """P+ of (CI) for the weight w in (0, 1] (P itself at w = 1)."""
    if w >= 1.0:
        return p
    pw = p / w
    ph, _, s_inv = ekf.innovation(pw, h, r / (1.0 - w))
    return pw - ph @ s_inv @ ph.T


def ci_update(
    x: np.ndarray, p: np.ndarray, nu: np.ndarray, h: np.ndarray, r: np.ndarray, w: float
) -> tuple[np.ndarray, np.ndarray]:
    """(x+, P+) of (CI) with innovation ``nu``, in Joseph form; (x, P) at w = 1."""
    if w >= 1.0:
        return x, p
    pw, rw = p / w, r / (1.0 - w)
    ph, _, s_inv = ekf.innovation(pw, h, rw)
    x, p = ekf.joseph_update(x, pw, nu, h, rw, ph, s_inv)
    return x, 0.5 * (p + p.T)


def split_ci_weight(
    p: np.ndarray,
    h: np.ndarray,
    r_dep: np.ndarray,
    r_ind: np.ndarray,
    criterion: str = "det",
    block: int = 3,
) -> float:
    """The SCI weight w in (0, 1] (1: the measurement adds nothing) minimising det or
    trace of P+[:block, :block], on a grid of 32 weights refined twice around the best."""
    if criterion not in ("det", "trace"):
        raise ValueError(f"criterion must be 'det' or 'trace', got {criterion!r}")
    pb = p[:block, :block]
    u = p[:block] @ h.T  # (block, m)
    a = h @ p @ h.T
    measure = np.linalg.det if criterion == "det" else (lambda m: np.trace(m, axis1=1, axis2=2))

    def crit(w: np.ndarray) -> np.ndarray:
        s = a[None] / w[:, None, None] + r_dep[None] / (1.0 - w)[:, None, None] + r_ind[None]
        uw = u[None] / w[:, None, None]
        post = pb[None] / w[:, None, None] - uw @ np.linalg.solve(s, np.swapaxes(uw, 1, 2))
        return measure(post)

    f1 = float(measure(pb[None])[0])
    grid = np.linspace(0.0, 1.0, 34)[1:-1]
    best = math.inf
    w = 1.0
    for _ in range(3):
        vals = crit(grid)
        i = int(np.argmin(vals))
        if vals[i] < best:
            best, w = float(vals[i]), float(grid[i])
        step = grid[1] - grid[0]
        grid = np.linspace(max(w - step, 1e-4), min(w + step, 1.0 - 1e-6), 17)
    return w if best < f1 * (1.0 - 1e-9) else 1.0


def split_ci_update(
    x: np.ndarray,
    p: np.ndarray,
    nu: np.ndarray,
    h: np.ndarray,
    r_dep: np.ndarray,
    r_ind: np.ndarray,
    w: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(x+, P+) of (SCI) with innovation ``nu``, in Joseph form; (x, P) at w = 1."""
    if w >= 1.0:
        return x, p
    pw, rw = p / w, r_dep / (1.0 - w) + r_ind
    ph, _, s_inv = ekf.innovation(pw, h, rw)
    x, p = ekf.joseph_update(x, pw, nu, h, rw, ph, s_inv)
    return x, 0.5 * (p + p.T)


def split_ci_posterior(
    p: np.ndarray, h: np.ndarray, r_dep: np.ndarray, r_ind: np.ndarray, w: float
) -> np.ndarray:
    """P+ of (SCI) for the weight w in (0, 1] (P itself at w = 1)."""
    return split_ci_update(np.zeros(p.shape[0]), p, np.zeros(h.shape[0]), h, r_dep, r_ind, w)[1]


def _golden(f) -> float:
    """Minimiser of f on [1e-3, 1] by golden-section search (f unimodal there); 1 when f
    does not decrease away from 1 or the search does not beat f(1)."""
    f1 = f(1.0)
    if f(1.0 - 1e-3) >= f1:
        return 1.0
    g = (math.sqrt(5.0) - 1.0) / 2.0
    lo, hi = 1e-3, 1.0
    c, d = hi - g * (hi - lo), lo + g * (hi - lo)
    fc, fd = f(c), f(d)
    for _ in range(30):
        if fc < fd:
            hi, d, fd = d, c, fc
            c = hi - g * (hi - lo)
            fc = f(c)
        else:
            lo, c, fc = c, d, fd
            d = lo + g * (hi - lo)
            fd = f(d)
    w = 0.5 * (lo + hi)
    return w if f(w) < f1 else 1.0
