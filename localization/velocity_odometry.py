"""Velocity odometry with guaranteed bounds for the real-robot window solver: the
commanded (v, w) of a robot (MRCLAM's odometry files, a Pioneer's cmd_vel) integrated
between two instants, and the bounded error model that turns it into interval
constraints between consecutive states (``localization.cp_rb_solve``).

**Integration.** Commands are held between their stamps (zero-order hold) and act
``lag_s`` after them (MRCLAM: the motion trails the commands by 0.16-0.20 s). Over a
step the integrator gives the commanded path length S = int v, the heading change
H = int w, the lowest and highest commanded heading reached inside the step (relative to
its start), the turn int |w|, the distance int |v|, and U, the time during which no command was fresh (older
than ``max_hold_s``, or none yet) and the motion is only bounded by the speed caps.

**Heading error model.** The error of the integrated heading E(t) = theta(t) - H(t) is a
slow drift plus a bounded transient (the response to each command change):
E = c + s with |s| <= a/2 and |c(t1) - c(t0)| <= b |t1 - t0| + b_m int |v| + r int |w|
+ w_cap U (a drift rate b, a drift b_m per metre driven and a fraction r of the
commanded turn). This is equivalent to the pair condition
|E(t1) - E(t0)| <= a + b dt + b_m int|v| + r int|w| over every pair of instants, which is
what the data shows (transients do not add up step after step); the solver carries c as
an exact chain and s per state, so a window of many short steps is not charged a per
step. Per step the offset increment bound is ``dc`` below.

**A second pair condition for long turns.** The error is not proportional to the turn:
a short turn can be missed by a large fraction of it (the response to a turn command),
a long one only by the turn rate's scale error (3-8 % on MRCLAM). One line a + r S
through both is loose for long turns, so the same pair condition also holds with a
larger transient and a smaller turn fraction, |E(t1) - E(t0)| <= a2 + b dt + b_m
int|v| + r2 int|w| (+ w_cap U). Both hold at once, so the heading at t1 is within the
smaller of the two bounds of the heading at t0 plus the commanded turn: ``dw`` below,
used by the solver as a chain on the headings themselves (next to the offset chain)
and by the prediction (a blind stretch with a long turn: 0.12 + 0.3 x 3 rad against
0.17 + 0.12 x 3 rad).

**Position error model.** The displacement over a step is D = int v u(theta) with u the
unit vector, so each component lies in L * cos(Phi) (resp. sin), L = int v >= 0 the true
path length and Phi the hull of the headings inside the step, plus a slack e for pushes
and sideways motion; L is within [L_lo, L_hi] of the commanded S, and |D| per axis is
below ``v_cap dt + e`` (a speed cap). Phi = Theta_k + [hmin, hmax] + c + s with c inside
both end states' offsets widened by ``dc``.

Bounds come from ``RangeBearingCPConfig`` (``localization.cp_config``), which documents
how their defaults were derived.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from localization import interval_kernels as K

#: Covers the rounding of sums of commanded headings (for |Theta| < 1e4 rad the sums'
#: rounding is below 1e-12 rad; the model's own bounds are 1e-3 rad and more).
GUARD = 1e-9


@dataclass
class StepIntegral:
    """Commanded motion over one step (seconds, metres, radians)."""

    dt: float = 0.0
    s: float = 0.0  # int v
    h: float = 0.0  # int w
    hmin: float = 0.0  # lowest int w reached inside the step (<= 0)
    hmax: float = 0.0  # highest (>= 0)
    turn: float = 0.0  # int |w|
    unknown: float = 0.0  # time without a fresh command
    dist: float = 0.0  # int |v|


def combine(a: StepIntegral, b: StepIntegral) -> StepIntegral:
    """The integral over two consecutive steps (``a`` then ``b``)."""
    return StepIntegral(
        a.dt + b.dt, a.s + b.s, a.h + b.h, min(a.hmin, a.h + b.hmin), max(a.hmax, a.h + b.hmax),
        a.turn + b.turn, a.unknown + b.unknown, a.dist + b.dist,
    )  # fmt: skip


class CommandIntegrator:
    """Streams stamped commands (in time order) and integrates them up to any instant;
    :meth:`take` returns the integral since the last take and starts a new step."""

    def __init__(self, lag_s: float, max_hold_s: float) -> None:
        self.lag = float(lag_s)
        self.max_hold = float(max_hold_s)
        self._pending: deque[tuple[float, float, float]] = deque()
        self.t: float | None = None  # integrated up to here
        self._v = self._w = 0.0
        self._t_cmd: float | None = None  # when the command in force took effect
        self.heading = 0.0  # int w since the first instant (absolute)
        self._step = StepIntegral()
        self.skipped = 0  # commands out of order or not finite

    def command(self, t: float, v: float, w: float) -> None:
        te = t + self.lag
        if not (np.isfinite(te) and np.isfinite(v) and np.isfinite(w)) or (
            self._pending and te < self._pending[-1][0]
        ):
            self.skipped += 1
            return
        self._pending.append((te, float(v), float(w)))

    def _run(self, t1: float) -> None:
        """Integrate the command in force from ``self.t`` to ``t1``."""
        t0 = self.t
        if t1 <= t0:
            return
        st = self._step
        dt = t1 - t0
        if self._t_cmd is None:
            stale = dt
        else:
            stale = max(0.0, t1 - max(t0, self._t_cmd + self.max_hold))
            st.s += self._v * dt
            st.h += self._w * dt
            st.turn += abs(self._w) * dt
            st.dist += abs(self._v) * dt
            self.heading += self._w * dt
            st.hmin, st.hmax = min(st.hmin, st.h), max(st.hmax, st.h)
        st.dt += dt
        st.unknown += stale
        self.t = t1

    def advance(self, t: float) -> None:
        """Integrate up to ``t`` (never backwards)."""
        if self.t is None:
            self.t = float(t)
        p = self._pending
        while p and p[0][0] <= t:
            te, v, w = p.popleft()
            if te > self.t:
                self._run(te)
            self._v, self._w, self._t_cmd = v, w, te
        if t > self.t:
            self._run(float(t))

    def peek(self) -> StepIntegral:
        """The integral since the last :meth:`take` (a copy)."""
        s = self._step
        return StepIntegral(s.dt, s.s, s.h, s.hmin, s.hmax, s.turn, s.unknown, s.dist)

    def take(self) -> StepIntegral:
        out, self._step = self._step, StepIntegral()
        return out


@dataclass(frozen=True)
class StepBounds:
    """Interval data of a step, as the solver uses it."""

    dc: float  # offset increment bound (rad)
    dw: float  # bound of E(t1) - E(t0) over any two instants of the step (rad)
    hmin: float  # commanded heading hull inside the step, relative to its start (rad)
    hmax: float
    l_lo: float  # path length bounds (m)
    l_hi: float
    slack: float  # per-axis slack (m)
    cap: float  # per-axis displacement cap (m)


def step_bounds(st: StepIntegral, cfg) -> StepBounds:
    """The error model of the module doc with the bounds of ``cfg``
    (a ``RangeBearingCPConfig``)."""
    b = bounds_arrays(*(np.array([v]) for v in (st.dt, st.s, st.turn, st.unknown, st.dist)), cfg)
    return StepBounds(
        float(b[0][0]), float(b[1][0]), st.hmin, st.hmax, *(float(v[0]) for v in b[2:])
    )


def bounds_arrays(dt, s, turn, unknown, dist, cfg) -> tuple[np.ndarray, ...]:
    """(dc, dw, l_lo, l_hi, slack, cap) of steps given as arrays (module doc's model)."""
    base = cfg.heading_drift_radps * dt + cfg.heading_drift_per_m * dist
    base = base + cfg.yaw_rate_cap_radps * unknown + GUARD
    dc = base + cfg.heading_turn_rel * turn
    long = base + cfg.heading_turn_rel_long * turn + cfg.heading_transient_long_rad
    dw = np.where(dt > 0.0, np.minimum(dc + cfg.heading_transient_rad, long), GUARD)
    p = cfg.path_abs_m + cfg.path_drift_mps * dt
    l_hi = (1.0 + cfg.speed_rel_hi) * s + p + cfg.speed_cap_mps * unknown
    l_lo = np.where(unknown > 0.0, 0.0, np.maximum(0.0, (1.0 - cfg.speed_rel_lo) * s - p))
    slack = cfg.slack_abs_m + cfg.slack_drift_mps * dt
    cap = cfg.speed_cap_mps * dt + cfg.slack_abs_m
    return dc, dw, l_lo, l_hi, slack, cap


def displacements(
    theta0: np.ndarray,
    hmin: np.ndarray,
    hmax: np.ndarray,
    c_lo: np.ndarray,
    c_hi: np.ndarray,
    half_a: float,
    l_lo: np.ndarray,
    l_hi: np.ndarray,
    slack: np.ndarray,
    cap: np.ndarray,
    also: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Intervals (dx_lo, dx_hi, dy_lo, dy_hi) of steps whose headings lie in
    ``theta0 + [hmin, hmax] + [c_lo, c_hi] +- half_a`` (the offset already widened by
    the step's dc) and, if given, in ``also`` (lo, hi) (the same headings bounded
    another way, in the same representation), path lengths in [l_lo, l_hi] (>= 0)."""
    pl, ph = K.add(theta0 + hmin, theta0 + hmax, c_lo, c_hi)
    pl, ph = K.add(pl, ph, -half_a - GUARD, half_a + GUARD)
    if also is not None:  # where the two meet (where they do not, the piece is dead)
        ml, mh = np.maximum(pl, also[0]), np.minimum(ph, also[1])
        ok = ml <= mh
        pl, ph = np.where(ok, ml, pl), np.where(ok, mh, ph)
    cl, ch, sl, sh = K.cos_sin(pl, ph)
    xl, xh = K.mul(l_lo, l_hi, cl, ch)
    yl, yh = K.mul(l_lo, l_hi, sl, sh)
    xl, xh = K.add(xl, xh, -slack, slack)
    yl, yh = K.add(yl, yh, -slack, slack)
    return np.maximum(xl, -cap), np.minimum(xh, cap), np.maximum(yl, -cap), np.minimum(yh, cap)


def predict_boxes(b: np.ndarray, theta0: np.ndarray, steps: list[StepIntegral], cfg) -> np.ndarray:
    """Boxes (N, 2, 3) of x, y, heading after ``steps`` from solved states ``b``
    (N, 2, 4: x, y, th, c; lo row, hi row) whose commanded headings are ``theta0``: the
    step model of the module doc forward (what a robot publishes between observations)."""
    f = np.array([(s.dt, s.s, s.h, s.hmin, s.hmax, s.turn, s.unknown, s.dist) for s in steps]).T
    dt, s, h, hmin, hmax, turn, unknown, dist = f.reshape(8, -1)
    dc, dw, l_lo, l_hi, slack, cap = bounds_arrays(dt, s, turn, unknown, dist, cfg)
    half_a = 0.5 * cfg.heading_transient_rad
    cl, ch = K.add(b[:, 0, 3], b[:, 1, 3], -dc, dc)
    # the headings inside the steps, also from the state's own heading (the pair bound)
    hl, hh = K.add(b[:, 0, 2] + hmin, b[:, 1, 2] + hmax, -dw, dw)
    dxl, dxh, dyl, dyh = displacements(
        theta0, hmin, hmax, cl, ch, half_a, l_lo, l_hi, slack, cap, (hl, hh)
    )
    out = np.empty((b.shape[0], 2, 3))
    out[:, 0, 0], out[:, 1, 0] = K.add(b[:, 0, 0], b[:, 1, 0], dxl, dxh)
    out[:, 0, 1], out[:, 1, 1] = K.add(b[:, 0, 1], b[:, 1, 1], dyl, dyh)
    # heading: through the offset, and from the state's own heading
    tl, th = K.add(theta0 + h + cl, theta0 + h + ch, -half_a - GUARD, half_a + GUARD)
    dl, dh = K.add(b[:, 0, 2] + h, b[:, 1, 2] + h, -dw, dw)
    out[:, 0, 2], out[:, 1, 2] = np.maximum(tl, dl), np.minimum(th, dh)
    return out


def predict_hulls(
    pieces: list[np.ndarray], theta0: np.ndarray, steps: list[StepIntegral], cfg
) -> np.ndarray:
    """Boxes (N, 2, 3) after ``steps[i]`` from the solved state ``i`` given as pieces
    ``pieces[i]`` (B_i, 2, 4) (a sub-paving: the state lies in one of them): each
    piece predicted (:func:`predict_boxes`) and the hull of state i's pieces taken."""
    sizes = np.array([p.shape[0] for p in pieces])
    b = np.concatenate(pieces)
    idx = np.repeat(np.arange(len(pieces)), sizes)
    out = predict_boxes(b, np.asarray(theta0)[idx], [steps[i] for i in idx], cfg)
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    hull = np.empty((len(pieces), 2, 3))
    hull[:, 0] = np.minimum.reduceat(out[:, 0], start, axis=0)
    hull[:, 1] = np.maximum.reduceat(out[:, 1], start, axis=0)
    return hull
