"""Interval localization over a sliding window of past states (ekf-vs-cp.txt eq. (5)):
the window's per-step arrays and the array-level API that fills and reads them.

Every state of the window keeps hard boxes (never dropped: the prior, gyro headings,
peer contractions), at most one GPS box (relaxable by the solver), and the wheel
displacement intervals of the step into it (eq. (1), bounds from the wheel errors).
When a state leaves the window its solved box becomes a hard prior of the next one, so
nothing learnt is lost and the cost per step is bounded.

The window is solved (``localization.cp_solve``) once per step (at the next ``step``,
or on :meth:`SlidingWindowCP.solve`); between solves the latest box is the one-step
prediction from the solved window (eq. (2) in interval arithmetic) met with the step's
GPS box (when no outliers are tolerated) and the hard boxes (gyro, peers). Later
measurements thus tighten earlier boxes, and the earlier boxes the current one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from localization import cp_scalar as cps
from localization import interval_scalar as isc
from localization.contractors import contract_range_bearing, fixpoint, odometry_displacement
from localization.cp_config import CPConfig
from localization.cp_solve import WindowArrays, solve_window
from localization.intake import MessageIntake
from localization.interval import IV, align_angle, meet_angle

_WHOLE = (-math.inf, math.inf)


@dataclass
class SlidingWindow:
    """Per-step lists of the window, oldest first."""

    stamps: list[int] = field(default_factory=list)
    # Hard per-step boxes (lo, hi) of x, y, theta.
    hx: list[list[float]] = field(default_factory=list)
    hy: list[list[float]] = field(default_factory=list)
    hth: list[list[float]] = field(default_factory=list)
    # GPS per step: (x_lo, x_hi, y_lo, y_hi, stamp) or None.
    gps: list[tuple[float, float, float, float, int] | None] = field(default_factory=list)
    # Wheel displacement intervals of the step *into* each state (index 0 unused).
    dsr: list[tuple[float, float]] = field(default_factory=list)
    dsl: list[tuple[float, float]] = field(default_factory=list)

    def append(
        self,
        stamp_ns: int,
        hard: tuple[IV | None, IV | None, IV | None],
        dsr: tuple[float, float],
        dsl: tuple[float, float],
    ) -> None:
        """A new latest state with hard boxes ``hard`` (None: the whole line)."""
        self.stamps.append(int(stamp_ns))
        for lst, iv in zip((self.hx, self.hy, self.hth), hard, strict=True):
            lst.append(list(_WHOLE) if iv is None else [float(iv.lo), float(iv.hi)])
        self.gps.append(None)
        self.dsr.append(dsr)
        self.dsl.append(dsl)

    def drop_oldest(self, x: IV, y: IV, th: IV) -> None:
        """Drop state 0, its knowledge kept by meeting the solved boxes ``x``, ``y``,
        ``th`` of the window into state 1's hard boxes."""
        for lst, iv in ((self.hx, x), (self.hy, y), (self.hth, th)):
            lst[1] = [max(lst[1][0], float(iv.lo[1])), min(lst[1][1], float(iv.hi[1]))]
        for lst in (self.stamps, self.hx, self.hy, self.hth, self.gps, self.dsr, self.dsl):
            del lst[0]

    def hard_latest(self) -> tuple[IV, IV, IV]:
        return IV.of(*self.hx[-1]), IV.of(*self.hy[-1]), IV.of(*self.hth[-1])

    def arrays(self) -> WindowArrays:
        hx = IV.of(*np.array(self.hx, dtype=float).T)
        hy = IV.of(*np.array(self.hy, dtype=float).T)
        hth = IV.of(*np.array(self.hth, dtype=float).T)
        r = np.array(self.dsr[1:], dtype=float).reshape(-1, 2)
        l = np.array(self.dsl[1:], dtype=float).reshape(-1, 2)
        dsr, dsl = IV.of(r[:, 0], r[:, 1]), IV.of(l[:, 0], l[:, 1])
        has = np.array([g is not None for g in self.gps])
        g = np.array([gg[:4] if gg is not None else (0.0, 0.0, 0.0, 0.0) for gg in self.gps])
        gx, gy = IV.of(g[:, 0], g[:, 1]), IV.of(g[:, 2], g[:, 3])
        return WindowArrays(hx, hy, hth, dsr, dsl, has, gx, gy)


class SlidingWindowCP(MessageIntake):
    """Array-level sliding-window constraint propagation for one robot (module doc)."""

    #: Contract one box against peers on floats (``localization.cp_scalar``) where it
    #: applies; False: always the array path (the reference, for tests and benches).
    scalar_path: bool = True

    def __init__(self, config: CPConfig | None = None) -> None:
        self.cfg = config or CPConfig()
        self._w = SlidingWindow()
        self._sol: tuple[IV, IV, IV] | None = None
        self._pred: tuple[IV, IV, IV] | None = None
        self._dirty = True
        self._soft = True  # dirty for a reason other than a new hard box
        self.dropped_gps: list[int] = []  # stamps of GPS fixes found inconsistent
        self.skipped: dict[str, int] = {}
        self.relaxations = 0  # solves that needed more than gps_outliers
        self.e = IV.around(self.cfg.wheelbase_m, self.cfg.wheelbase_bound_m)

    @property
    def started(self) -> bool:
        return bool(self._w.stamps)

    def start(
        self, stamp_ns: int, x: IV | None = None, y: IV | None = None, th: IV | None = None
    ) -> None:
        """First state; unknown components default to the whole line."""
        self._w.append(stamp_ns, (x, y, th), (0.0, 0.0), (0.0, 0.0))
        self._dirty = self._soft = True

    def step(self, stamp_ns: int, dsr: float, dsl: float) -> None:
        """A new state, ``dsr``/``dsl`` metres of measured wheel travel after the last."""
        if not self.started:
            raise RuntimeError("CPLocalizer.step before start")
        c = self.cfg
        br = c.wheel_abs_bound_m + c.wheel_rel_bound * abs(dsr)
        bl = c.wheel_abs_bound_m + c.wheel_rel_bound * abs(dsl)
        r, l = IV.around(dsr, br), IV.around(dsl, bl)
        # Solve the finished window once (its smoothed last state seeds the prediction).
        if self._soft or self._sol is None:
            self._solve()
        if len(self._w.stamps) >= max(c.window, 1) + 1:
            self._slide()
        rr, ll = (float(r.lo), float(r.hi)), (float(l.lo), float(l.hi))
        pred = self._predict_f(rr, ll) if self.scalar_path else None
        if pred is None:
            x0, y0, th0 = self._latest()
            dx, dy, dth = odometry_displacement(
                th0, th0 + (r - l) / self.e, r, l, self.e, c.kappa, c.chord
            )
            pred = (x0 + dx, y0 + dy, th0 + dth)
        self._w.append(stamp_ns, (None, None, None), rr, ll)
        self._pred = pred
        self._dirty = self._soft = True

    def _predict_f(self, r: isc.Iv, l: isc.Iv) -> tuple[IV, IV, IV] | None:
        """The one-step prediction of :meth:`step` (eq. (2) forward) on floats; None
        where the scalar path does not apply (an unbounded or empty heading)."""
        x0, y0, th0 = self._latest_f()
        e = (float(self.e.lo), float(self.e.hi))
        try:
            dx, dy, dth = cps.odometry_displacement(
                th0,
                isc.add(th0, isc.div(isc.sub(r, l), e)),
                r,
                l,
                e,
                self.cfg.kappa,
                self.cfg.chord,
            )
        except isc.Fallback:
            return None
        return tuple(IV.of(*isc.add(a, b)) for a, b in ((x0, dx), (y0, dy), (th0, dth)))  # type: ignore[return-value]

    def _slide(self) -> None:
        """Drop the oldest state; its knowledge survives as the next state's prior."""
        if self._soft or self._sol is None:
            self._solve()
        self._w.drop_oldest(*self._sol)
        self._sol = tuple(v[1:] for v in self._sol)
        self._soft = False

    def _age_s(self, stamp_ns: int) -> float:
        return abs(int(stamp_ns) - self._w.stamps[-1]) * 1e-9

    def gps(self, stamp_ns: int, east: float, north: float, bound: float | None = None) -> None:
        """A GPS fix; attached to the latest state, widened for a stamp difference."""
        if not self.started:
            raise RuntimeError("CPLocalizer.gps before start")
        b = (
            self.cfg.gps_bound_m if bound is None else bound
        ) + self.cfg.speed_bound_mps * self._age_s(stamp_ns)
        xi, yi = IV.around(east, b), IV.around(north, b)
        self._w.gps[-1] = (float(xi.lo), float(xi.hi), float(yi.lo), float(yi.hi), int(stamp_ns))
        self._dirty = self._soft = True

    def heading(self, stamp_ns: int, theta: IV) -> None:
        """A guaranteed heading interval for the latest state (e.g. the gyro's)."""
        if not self.started:
            raise RuntimeError("CPLocalizer.heading before start")
        theta = theta.inflate(self.cfg.yaw_rate_bound_radps * self._age_s(stamp_ns))
        self._hard(self._w.hth, theta, angle=True)

    def position_box(self, x: IV, y: IV) -> None:
        """A hard (never dropped) position box for the latest state."""
        self._hard(self._w.hx, x)
        self._hard(self._w.hy, y)

    def _hard(self, lst: list[list[float]], iv: IV, angle: bool = False) -> None:
        self._hard_f(lst, float(iv.lo), float(iv.hi), angle)

    def _hard_f(self, lst: list[list[float]], lo: float, hi: float, angle: bool = False) -> None:
        cur = lst[-1]
        if angle and not self.scalar_path:  # the reference of the scalar path
            iv = IV.of(lo, hi)
            known = IV.of(cur[0], cur[1]) & self._theta_ref()
            if np.isneginf(known.lo) and np.isposinf(known.hi):
                iv = align_angle(iv, 0.0)
            else:
                iv = meet_angle(known, iv)
            lo, hi = float(iv.lo), float(iv.hi)
        elif angle:
            # Meet modulo 2*pi, inside what is known of this heading already (its hard box
            # and the latest solution or prediction: all in the chain's representation),
            # over every branch of ``iv`` that meets it.
            ref = self._theta_ref()
            known = isc.meet((cur[0], cur[1]), (float(ref.lo), float(ref.hi)))
            if known == (-math.inf, math.inf):
                # Nothing known of any heading of the window yet: the representation is
                # free (shifting every heading by 2*pi*k keeps every constraint), so the
                # first heading fixes it on the branch of ``iv`` next to 0.
                iv = align_angle(IV.of(lo, hi), 0.0)
                lo, hi = float(iv.lo), float(iv.hi)
            elif lo <= hi:
                lo, hi = isc.meet_angle_s(known, (lo, hi))
            else:
                lo, hi = isc.EMPTY
        cur[0] = max(cur[0], lo)
        cur[1] = min(cur[1], hi)
        self._dirty = True

    def _theta_ref(self) -> IV:
        n = len(self._w.stamps)
        if self._sol is not None and self._sol[2].lo.shape[0] == n and not self._soft:
            return self._sol[2][-1]
        if self._pred is not None and self._sol is not None and self._sol[2].lo.shape[0] == n - 1:
            return self._pred[2]
        if self._sol is not None and self._sol[2].lo.shape[0] == n:
            return self._sol[2][-1]
        return IV.entire(())

    def relative(self, stamp_ns: int, peer_x: IV, peer_y: IV, rho: IV, beta: IV) -> bool:
        """Range ``rho`` and bearing ``beta`` (own body frame) to peers inside the boxes
        ``peer_x x peer_y`` (valid at ``stamp_ns``; arrays of shape (m,) for m peers at
        once). Contracts the latest state; returns False (and changes nothing) if the
        measurements are inconsistent with it."""
        if self.scalar_path:
            peers = _peer_tuples(peer_x, peer_y, rho, beta)
            if peers is not None and self.relative_f(stamp_ns, peers):
                return True
        x, y, th = self._latest()
        # A measurement off the state's stamp: the own motion and turn since are bounded.
        age_s = self._age_s(stamp_ns)
        grow = self.cfg.speed_bound_mps * age_s  # own motion between state and measurement
        turn = self.cfg.yaw_rate_bound_radps * age_s
        beta = beta.inflate(turn)
        (xi, yi, thi, *_), _ = fixpoint(
            contract_range_bearing,
            [x, y, th, peer_x.inflate(grow), peer_y.inflate(grow), rho, beta],
            tol=self.cfg.tol,
            max_iter=4,
        )
        xi, yi = _meet(xi), _meet(yi)
        thi = _meet(thi)  # every peer's result is a subset of th: same 2*pi branch
        if bool(xi.is_empty() | yi.is_empty() | thi.is_empty()):
            self._skip("inconsistent_relative")
            return False
        self.position_box(xi, yi)
        self._hard(self._w.hth, thi, angle=True)
        return True

    def relative_f(self, stamp_ns: int, peers: list[tuple[isc.Iv, ...]]) -> bool | None:
        """:meth:`relative` on floats (``localization.cp_scalar``): ``peers`` holds
        (peer x, peer y, rho, beta) bounds per peer. True when the box was contracted;
        None where the scalar path does not apply (unbounded or empty boxes, a proven
        inconsistency): the caller then runs :meth:`relative`'s array path."""
        age_s = self._age_s(stamp_ns)
        grow = self.cfg.speed_bound_mps * age_s
        turn = self.cfg.yaw_rate_bound_radps * age_s
        inf = isc.inflate
        ps = [(inf(px, grow), inf(py, grow), r, inf(b, turn)) for px, py, r, b in peers]
        try:
            (xl, xh), (yl, yh), (tl, th) = cps.relative_fixpoint(
                self._latest_f(), ps, self.cfg.tol, 4
            )
        except isc.Fallback:
            return None
        self._hard_f(self._w.hx, xl, xh)
        self._hard_f(self._w.hy, yl, yh)
        self._hard_f(self._w.hth, tl, th, angle=True)
        return True

    def _latest(self) -> tuple[IV, IV, IV]:
        """The latest box without a window solve when possible (:meth:`_latest_f`)."""
        if not self.scalar_path:
            return self._latest_iv()
        return tuple(IV.of(lo, hi) for lo, hi in self._latest_f())  # type: ignore[return-value]

    def _latest_iv(self) -> tuple[IV, IV, IV]:
        """:meth:`_latest_f` on interval arrays (the reference of the scalar path)."""
        w = self._w
        n = len(w.stamps)
        if self._sol is not None and not self._soft and self._sol[0].lo.shape[0] == n:
            x, y, th = (v[-1] for v in self._sol)
        elif self._pred is not None and self._sol is not None and self._sol[0].lo.shape[0] == n - 1:
            x, y, th = self._pred
            g = w.gps[-1]
            if g is not None and self.cfg.gps_outliers == 0:
                x, y = x & IV.of(g[0], g[1]), y & IV.of(g[2], g[3])
                if bool(x.is_empty() | y.is_empty()):
                    x, y, th = (v[-1] for v in self._solve())
        else:
            x, y, th = (v[-1] for v in self._solve())
        hx, hy, hth = w.hard_latest()
        return x & hx, y & hy, th & hth

    def _latest_f(self) -> tuple[isc.Iv, isc.Iv, isc.Iv]:
        """The latest box as float bounds, without a window solve when possible: the
        last solution (or the one-step prediction from it, met with this step's GPS box
        unless outliers are tolerated) met with the hard boxes added since. Valid, and
        the window solve at the next step (or :meth:`solve`) brings in the smoothing and
        relaxation. Empties are (inf, -inf)."""
        w = self._w
        n = len(w.stamps)
        sol = self._sol
        if sol is not None and not self._soft and sol[0].lo.shape[0] == n:
            x, y, th = (_last(v) for v in sol)
        elif self._pred is not None and sol is not None and sol[0].lo.shape[0] == n - 1:
            x, y, th = ((float(v.lo), float(v.hi)) for v in self._pred)
            g = w.gps[-1]
            if g is not None and self.cfg.gps_outliers == 0:
                x, y = isc.meet(x, (g[0], g[1])), isc.meet(y, (g[2], g[3]))
                if x == isc.EMPTY or y == isc.EMPTY:  # inconsistent fix: let the solver relax
                    x, y, th = (_last(v) for v in self._solve())
        else:
            x, y, th = (_last(v) for v in self._solve())
        # hth and th are both in the chain's representation of the heading (every hard
        # heading is met inside it by _hard): a plain intersection.
        return (
            isc.meet(x, tuple(w.hx[-1])),
            isc.meet(y, tuple(w.hy[-1])),
            isc.meet(th, tuple(w.hth[-1])),
        )

    def solve(self) -> tuple[IV, IV, IV]:
        """Solve the whole window now; returns the latest box."""
        x, y, th = self._solve()
        return x[-1], y[-1], th[-1]

    def current(self) -> tuple[IV, IV, IV]:
        """Box (x, y, theta) of the latest state (theta unwrapped). Hard boxes added
        since the last solve are met directly; the window is re-solved on the next step
        or by :meth:`window_arrays`."""
        return self._latest()

    def window_arrays(self) -> tuple[list[int], IV, IV, IV]:
        x, y, th = self._solve()
        return list(self._w.stamps), x, y, th

    def _solve(self) -> tuple[IV, IV, IV]:
        if not self._dirty and self._sol is not None:
            return self._sol
        s = solve_window(self._w.arrays(), self.cfg, self.e)
        if s.relaxed:
            self.relaxations += 1
        for k in s.inconsistent_gps:
            st = self._w.gps[k][4]
            if st not in self.dropped_gps:
                self.dropped_gps.append(st)
        self._sol = (s.x, s.y, s.th)
        self._dirty = self._soft = False
        return self._sol


def _peer_tuples(px: IV, py: IV, rho: IV, beta: IV) -> list[tuple[isc.Iv, ...]] | None:
    """The per-peer float bounds of :meth:`SlidingWindowCP.relative`'s arrays (None if
    their shapes do not broadcast to one axis of peers)."""
    cols = [np.atleast_1d(a).tolist() for v in (px, py, rho, beta) for a in (v.lo, v.hi)]
    n = max(len(c) for c in cols)
    if n == 0 or any(len(c) not in (1, n) or isinstance(c[0], list) for c in cols):
        return None
    cols = [c * n if len(c) == 1 else c for c in cols]
    return [((a, b), (c, d), (e, f), (g, h)) for a, b, c, d, e, f, g, h in zip(*cols, strict=True)]


def _last(v: IV) -> isc.Iv:
    return float(v.lo[-1]), float(v.hi[-1])


def _meet(v: IV) -> IV:
    """Intersection of all intervals of an array (a scalar interval)."""
    return IV.of(np.max(v.lo), np.min(v.hi)) if np.ndim(v.lo) else v
