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

Here too the window's per-step lists (:class:`SlidingWindow`, which the array-level API
of ``localization.cp_window`` fills) and the solution as lists (:class:`SolutionF`).
This array solve is the reference; the daemon's solve is the incremental one on floats
(``localization.cp_incremental``), at least as tight, which falls back to this one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from localization.chain import chain, relaxed_chain
from localization.contractors import contract_odometry, odometry_displacement
from localization.cp_config import CPConfig
from localization.interval import IV

TH, X, Y = 0, 1, 2  # the axes of the hard boxes


@dataclass
class SlidingWindow:
    """The window's per-step lists, oldest first: stamps, hard boxes (never dropped: the
    prior, gyro headings, peer contractions) as lower and upper bounds per axis
    (``lo[TH]``, ``hi[X]``, ...; the whole line where nothing is known), at most one
    GPS box per step (relaxable by the solver), and the wheel displacement intervals of
    the step into each state (index 0 unused)."""

    stamps: list[int] = field(default_factory=list)
    lo: list[list[float]] = field(default_factory=lambda: [[], [], []])
    hi: list[list[float]] = field(default_factory=lambda: [[], [], []])
    # GPS per step: (x_lo, x_hi, y_lo, y_hi, stamp) or None.
    gps: list[tuple[float, float, float, float, int] | None] = field(default_factory=list)
    dsr: list[tuple[float, float]] = field(default_factory=list)
    dsl: list[tuple[float, float]] = field(default_factory=list)
    # The float solve's terms per step (localization.cp_incremental.StepTerms; None: not
    # made yet).
    terms: list[Any] = field(default_factory=list)

    def append(
        self,
        stamp_ns: int,
        hard: tuple[IV | None, IV | None, IV | None],
        dsr: tuple[float, float],
        dsl: tuple[float, float],
        terms: Any = None,
    ) -> None:
        """A new latest state with hard boxes ``hard`` (x, y, theta; None: the whole
        line)."""
        self.stamps.append(int(stamp_ns))
        for i, iv in ((X, hard[0]), (Y, hard[1]), (TH, hard[2])):
            self.lo[i].append(-math.inf if iv is None else float(iv.lo))
            self.hi[i].append(math.inf if iv is None else float(iv.hi))
        self.gps.append(None)
        self.dsr.append(dsr)
        self.dsl.append(dsl)
        self.terms.append(terms)

    def drop_oldest(self, state1: tuple[tuple[float, float], ...]) -> None:
        """Drop state 0, its knowledge kept by meeting the solved box ``state1``
        ((lo, hi) of theta, x, y) of state 1 into state 1's hard boxes."""
        for i, (lo, hi) in enumerate(state1):
            self.lo[i][1] = max(self.lo[i][1], lo)
            self.hi[i][1] = min(self.hi[i][1], hi)
        for lst in (self.stamps, *self.lo, *self.hi, self.gps, self.dsr, self.dsl, self.terms):
            del lst[0]

    def hard_latest(self) -> tuple[IV, IV, IV]:
        """The latest state's hard boxes x, y, theta."""
        return tuple(IV.of(self.lo[i][-1], self.hi[i][-1]) for i in (X, Y, TH))  # type: ignore[return-value]

    def arrays(self) -> WindowArrays:
        hx, hy, hth = (IV.of(np.array(self.lo[i]), np.array(self.hi[i])) for i in (X, Y, TH))
        r = np.array(self.dsr[1:], dtype=float).reshape(-1, 2)
        l = np.array(self.dsl[1:], dtype=float).reshape(-1, 2)
        dsr, dsl = IV.of(r[:, 0], r[:, 1]), IV.of(l[:, 0], l[:, 1])
        has = np.array([g is not None for g in self.gps])
        g = np.array([gg[:4] if gg is not None else (0.0, 0.0, 0.0, 0.0) for gg in self.gps])
        gx, gy = IV.of(g[:, 0], g[:, 1]), IV.of(g[:, 2], g[:, 3])
        return WindowArrays(hx, hy, hth, dsr, dsl, has, gx, gy)


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


@dataclass
class SolutionF:
    """:class:`WindowSolution` as lists of floats (x, y, theta lows and highs of every
    state), as the window keeps it."""

    xl: list[float]
    xh: list[float]
    yl: list[float]
    yh: list[float]
    tl: list[float]
    th: list[float]
    relaxed: bool
    inconsistent_gps: list[int]

    def __len__(self) -> int:
        return len(self.tl)

    def last(self) -> tuple[tuple[float, float], ...]:
        return (self.xl[-1], self.xh[-1]), (self.yl[-1], self.yh[-1]), (self.tl[-1], self.th[-1])

    def drop_first(self) -> None:
        """The solution of the window without its oldest state."""
        for v in (self.xl, self.xh, self.yl, self.yh, self.tl, self.th):
            del v[0]


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
