"""The contraction of a sliding window of poses (ekf-vs-cp.txt eq. (5)): the smallest
boxes the constraints allow on this decomposition.

The unknowns are the poses of the window; the constraints are the odometry model eq.
(1)-(2) between consecutive steps (wheel displacements known within bounds), hard boxes
per step (prior, gyro headings, peer contractions) and GPS position boxes:

1. heading: exact forward-backward chain ``theta[k+1] = theta[k] + dth[k]`` through
   every hard heading interval of the window (``localization.chain``);
2. displacements: eq. (2) in interval arithmetic, per step, with the contracted headings;
3. x and y: exact chains through the hard boxes and the q-relaxed chain through the GPS
   boxes, so up to ``gps_outliers`` wrong fixes in the window (a GPS jump outside its
   stated bound) neither empty nor bias the box. If the boxes still come out empty, q is
   raised until they do not (a relaxation), and the fixes found inconsistent are
   reported;
4. optionally (``hc4_odometry``) a vectorised HC4 pass of the odometry contractor over
   the whole window (positions back onto headings).

Steps 2-4 are repeated up to ``iterations`` times, until no box shrinks by more than
``tol`` (relative width).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from localization.chain import chain, relaxed_chain
from localization.contractors import contract_odometry, odometry_displacement
from localization.cp_config import CPConfig
from localization.interval import IV


@dataclass(frozen=True)
class WindowArrays:
    """The window of n states as the solver sees it: hard boxes ``hx``, ``hy``, ``hth``
    (n,), wheel displacements ``dsr``, ``dsl`` of the n - 1 steps, and GPS boxes
    ``gx``, ``gy`` (n,) where ``has_gps``."""

    hx: IV
    hy: IV
    hth: IV
    dsr: IV
    dsl: IV
    has_gps: np.ndarray
    gx: IV
    gy: IV


@dataclass(frozen=True)
class WindowSolution:
    """Boxes of every state, whether the GPS had to be relaxed beyond ``gps_outliers``,
    and the indices of the GPS fixes found inconsistent."""

    x: IV
    y: IV
    th: IV
    relaxed: bool
    inconsistent_gps: np.ndarray


def solve_window(a: WindowArrays, c: CPConfig, e: IV) -> WindowSolution:
    """Contract the window ``a`` (wheelbase interval ``e``); see the module doc."""
    has = a.has_gps
    th = chain(a.hth, (a.dsr - a.dsl) / e)
    x, y = a.hx, a.hy
    q_used = c.gps_outliers
    consistent = has
    for _ in range(max(1, c.iterations)):
        x_old, y_old, th_old = x, y, th
        dx, dy, _ = odometry_displacement(th[:-1], th[1:], a.dsr, a.dsl, e, c.kappa, c.chord)
        x, y, q, consistent = _positions(a, x, y, dx, dy, c.gps_outliers)
        q_used = max(q_used, q)
        if c.hc4_odometry and len(has) > 1:
            th = _hc4_headings(a, x, y, th, c, e)
        if (
            _shrink(x_old, x) <= c.tol
            and _shrink(y_old, y) <= c.tol
            and _shrink(th_old, th) <= c.tol
        ):
            break
    return WindowSolution(x, y, th, q_used > c.gps_outliers, np.flatnonzero(has & ~consistent))


def _positions(
    a: WindowArrays, x: IV, y: IV, dx: IV, dy: IV, q: int
) -> tuple[IV, IV, int, np.ndarray]:
    """Step 3: x and y through the hard chains and the q-relaxed GPS chain, q raised
    until the boxes are not empty (or every fix is relaxed). Returns x, y, the q used and
    which fixes are consistent with the result."""
    has = a.has_gps
    xs, ys = chain(a.hx & x, dx), chain(a.hy & y, dy)
    while True:
        rx, cx = relaxed_chain(a.gx, has, dx, q)
        ry, cy = relaxed_chain(a.gy, has, dy, q)
        nx, ny = chain(xs & rx, dx), chain(ys & ry, dy)
        bad = bool(np.any(nx.is_empty()) or np.any(ny.is_empty()))
        if not bad or q >= int(has.sum()):
            break
        q += 1
    return nx, ny, q, cx & cy


def _hc4_headings(a: WindowArrays, x: IV, y: IV, th: IV, c: CPConfig, e: IV) -> IV:
    """Step 4: the odometry contractor over every step, its heading contractions met into
    the heading chain."""
    x0, y0, th0, x1, y1, th1, _, _ = contract_odometry(
        x[:-1], y[:-1], th[:-1], x[1:], y[1:], th[1:], a.dsr, a.dsl, e, c.kappa, c.chord
    )
    th_c = IV(
        np.maximum(np.append(th0.lo, -np.inf), np.insert(th1.lo, 0, -np.inf)),
        np.minimum(np.append(th0.hi, np.inf), np.insert(th1.hi, 0, np.inf)),
    )
    return chain(th & th_c, (a.dsr - a.dsl) / e)


def _shrink(a: IV, b: IV) -> float:
    """Largest relative shrink of the finite widths from ``a`` to ``b``."""
    wa, wb = a.width(), b.width()
    fin = np.isfinite(wa) & np.isfinite(wb)
    if not np.any(fin):
        return 0.0 if np.all(np.isinf(wb) == np.isinf(wa)) else 1.0
    return float(np.max((wa[fin] - wb[fin]) / np.maximum(wa[fin], 1e-12), initial=0.0))
