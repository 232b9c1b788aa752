"""Interval localization over a sliding window of past states (ekf-vs-cp.txt eq. (5)):
the array-level API that fills the window (``cp_solve.SlidingWindow``) and reads it.

Every state of the window keeps hard boxes (never dropped: the prior, gyro headings,
peer contractions), at most one GPS box (relaxable by the solver), and the wheel
displacement intervals of the step into it (eq. (1), bounds from the wheel errors).
When a state leaves the window its solved box becomes a hard prior of the next one, so
nothing learnt is lost and the cost per step is bounded.

The window is solved once per step (at the next ``step``, or on
:meth:`SlidingWindowCP.solve`): on floats, incrementally (``localization.cp_incremental``:
from what changed since the last solve; bounds at least as tight as the array solve's),
or by the array solve of ``localization.cp_solve`` where that does not apply or when
``scalar_path`` is False. Between solves the latest box is the one-step
prediction from the solved window (eq. (2) in interval arithmetic) met with the step's
GPS box (when no outliers are tolerated) and the hard boxes (gyro, peers). Later
measurements thus tighten earlier boxes, and the earlier boxes the current one.
"""

from __future__ import annotations

import math

import numpy as np

from localization import cp_scalar as cps
from localization import interval_scalar as isc
from localization.contractors import contract_range_bearing, fixpoint, odometry_displacement
from localization.cp_config import CPConfig
from localization.cp_incremental import IncrementalSolver, StepTerms
from localization.cp_solve import TH, SlidingWindow, SolutionF, X, Y, solve_window
from localization.intake import MessageIntake
from localization.interval import IV, align_angle, meet_angle


class SlidingWindowCP(MessageIntake):
    """Array-level sliding-window constraint propagation for one robot (module doc)."""

    #: Solve the window and contract one box against peers on floats
    #: (``localization.cp_solve_scalar``, ``localization.cp_scalar``) where that applies;
    #: False: always the array path (the reference, for tests and benches).
    scalar_path: bool = True

    def __init__(self, config: CPConfig | None = None) -> None:
        self.cfg = config or CPConfig()
        self._w = SlidingWindow()
        self._sol: SolutionF | None = None
        self._pred: tuple[isc.Iv, isc.Iv, isc.Iv] | None = None
        self._dirty = True
        self._soft = True  # dirty for a reason other than a new hard box
        self.dropped_gps: list[int] = []  # stamps of GPS fixes found inconsistent
        self.skipped: dict[str, int] = {}
        self.relaxations = 0  # solves that needed more than gps_outliers
        self.e = IV.around(self.cfg.wheelbase_m, self.cfg.wheelbase_bound_m)
        self._ef = (float(self.e.lo), float(self.e.hi))
        self._inc = IncrementalSolver(self.cfg)

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
        r = isc.around(dsr, c.wheel_abs_bound_m + c.wheel_rel_bound * abs(dsr))
        l = isc.around(dsl, c.wheel_abs_bound_m + c.wheel_rel_bound * abs(dsl))
        # Solve the finished window once (its smoothed last state seeds the prediction).
        if self._soft or self._sol is None:
            self._solve()
        if len(self._w.stamps) >= max(c.window, 1) + 1:
            self._slide()
        terms = StepTerms(r, l, self._ef) if self.scalar_path else None
        pred = self._predict_f(terms) if terms is not None else None
        if pred is None:
            ri, li = IV.of(*r), IV.of(*l)
            x0, y0, th0 = self._latest()
            dx, dy, dth = odometry_displacement(
                th0, th0 + (ri - li) / self.e, ri, li, self.e, c.kappa, c.chord
            )
            pred = _floats(x0 + dx), _floats(y0 + dy), _floats(th0 + dth)
        self._w.append(stamp_ns, (None, None, None), r, l, terms)
        self._pred = pred
        self._dirty = self._soft = True

    def _predict_f(self, t: StepTerms) -> tuple[isc.Iv, isc.Iv, isc.Iv] | None:
        """The one-step prediction of :meth:`step` (eq. (2) forward) on floats from the
        step's wheel terms; None where the scalar path does not apply (an unbounded or
        empty heading)."""
        x0, y0, th0 = self._latest_f()
        if not (math.isfinite(th0[0]) and math.isfinite(th0[1]) and th0[0] <= th0[1]):
            return None
        try:
            dx, dy, dth = cps.displacement_dth(
                th0, isc.add(th0, t.dth), t.ds, t.dth, self.cfg.kappa, self.cfg.chord
            )
        except isc.Fallback:
            return None
        return isc.add(x0, dx), isc.add(y0, dy), isc.add(th0, dth)

    def _slide(self) -> None:
        """Drop the oldest state; its knowledge survives as the next state's prior."""
        sol = self._solve() if self._soft or self._sol is None else self._sol
        self._w.drop_oldest(
            ((sol.tl[1], sol.th[1]), (sol.xl[1], sol.xh[1]), (sol.yl[1], sol.yh[1]))
        )
        sol.drop_first()
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
        (xl, xh), (yl, yh) = isc.around(east, b), isc.around(north, b)
        self._w.gps[-1] = (xl, xh, yl, yh, int(stamp_ns))
        self._dirty = self._soft = True

    def heading(self, stamp_ns: int, theta: IV) -> None:
        """A guaranteed heading interval for the latest state (e.g. the gyro's)."""
        self.heading_f(stamp_ns, float(theta.lo), float(theta.hi))

    def heading_f(self, stamp_ns: int, lo: float, hi: float) -> None:
        """:meth:`heading` of the interval [lo, hi]."""
        if not self.started:
            raise RuntimeError("CPLocalizer.heading before start")
        iv = (lo, hi) if lo <= hi else isc.EMPTY
        lo, hi = isc.inflate(iv, self.cfg.yaw_rate_bound_radps * self._age_s(stamp_ns))
        self._hard_f(TH, lo, hi, angle=True)

    def position_box(self, x: IV, y: IV) -> None:
        """A hard (never dropped) position box for the latest state."""
        self._hard_f(X, float(x.lo), float(x.hi))
        self._hard_f(Y, float(y.lo), float(y.hi))

    def _hard_f(self, i: int, lo: float, hi: float, angle: bool = False) -> None:
        """Meet [lo, hi] into the latest state's hard box of axis ``i`` (TH, X, Y)."""
        los, his = self._w.lo[i], self._w.hi[i]
        cur = (los[-1], his[-1])
        if angle and not self.scalar_path:  # the reference of the scalar path
            iv = IV.of(lo, hi)
            known = IV.of(*cur) & IV.of(*self._theta_ref())
            if np.isneginf(known.lo) and np.isposinf(known.hi):
                iv = align_angle(iv, 0.0)
            else:
                iv = meet_angle(known, iv)
            lo, hi = float(iv.lo), float(iv.hi)
        elif angle:
            # Meet modulo 2*pi, inside what is known of this heading already (its hard box
            # and the latest solution or prediction: all in the chain's representation),
            # over every branch of ``iv`` that meets it.
            known = isc.meet(cur, self._theta_ref())
            if known == (-math.inf, math.inf):
                # Nothing known of any heading of the window yet: the representation is
                # free (shifting every heading by 2*pi*k keeps every constraint), so the
                # first heading fixes it on the branch of ``iv`` next to 0.
                lo, hi = _floats(align_angle(IV.of(lo, hi), 0.0))
            elif lo <= hi:
                lo, hi = isc.meet_angle_s(known, (lo, hi))
            else:
                lo, hi = isc.EMPTY
        los[-1] = max(cur[0], lo)
        his[-1] = min(cur[1], hi)
        self._dirty = True

    def _theta_ref(self) -> isc.Iv:
        """What the window knows of the latest heading: its solution, or the prediction
        from the last solution."""
        n, sol = len(self._w.stamps), self._sol
        m = -1 if sol is None else len(sol)
        if sol is not None and m == n and not self._soft:
            return sol.tl[-1], sol.th[-1]
        if self._pred is not None and m == n - 1:
            return self._pred[2]
        if sol is not None and m == n:
            return sol.tl[-1], sol.th[-1]
        return -math.inf, math.inf

    def relative(self, stamp_ns: int, peer_x: IV, peer_y: IV, rho: IV, beta: IV) -> bool:
        """Range ``rho`` and bearing ``beta`` (own body frame) to peers inside the boxes
        ``peer_x x peer_y`` (valid at ``stamp_ns``; arrays of shape (m,) for m peers at
        once). Contracts the latest state; returns False (and changes nothing) if the
        measurements are inconsistent with it. No peer (m = 0): nothing to contract,
        True."""
        if any(np.size(a) == 0 for v in (peer_x, peer_y, rho, beta) for a in (v.lo, v.hi)):
            return True
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
        self._hard_f(TH, float(thi.lo), float(thi.hi), angle=True)
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
        self._hard_f(X, xl, xh)
        self._hard_f(Y, yl, yh)
        self._hard_f(TH, tl, th, angle=True)
        return True

    def _latest(self) -> tuple[IV, IV, IV]:
        """The latest box without a window solve when possible (:meth:`_latest_f`)."""
        if not self.scalar_path:
            return self._latest_iv()
        return tuple(IV.of(lo, hi) for lo, hi in self._latest_f())  # type: ignore[return-value]

    def _latest_iv(self) -> tuple[IV, IV, IV]:
        """:meth:`_latest_f` on interval arrays (the reference of the scalar path)."""
        w, sol = self._w, self._sol
        n = len(w.stamps)
        if sol is not None and not self._soft and len(sol) == n:
            x, y, th = (IV.of(*v) for v in sol.last())
        elif self._pred is not None and sol is not None and len(sol) == n - 1:
            x, y, th = (IV.of(*v) for v in self._pred)
            g = w.gps[-1]
            if g is not None and self.cfg.gps_outliers == 0:
                x, y = x & IV.of(g[0], g[1]), y & IV.of(g[2], g[3])
                if bool(x.is_empty() | y.is_empty()):
                    x, y, th = (IV.of(*v) for v in self._solve().last())
        else:
            x, y, th = (IV.of(*v) for v in self._solve().last())
        hx, hy, hth = w.hard_latest()
        return x & hx, y & hy, th & hth

    def _latest_f(self) -> tuple[isc.Iv, isc.Iv, isc.Iv]:
        """The latest box as float bounds, without a window solve when possible: the
        last solution (or the one-step prediction from it, met with this step's GPS box
        unless outliers are tolerated) met with the hard boxes added since. Valid, and
        the window solve at the next step (or :meth:`solve`) brings in the smoothing and
        relaxation. Empties are (inf, -inf)."""
        w, sol = self._w, self._sol
        n = len(w.stamps)
        if sol is not None and not self._soft and len(sol) == n:
            x, y, th = sol.last()
        elif self._pred is not None and sol is not None and len(sol) == n - 1:
            x, y, th = self._pred
            g = w.gps[-1]
            if g is not None and self.cfg.gps_outliers == 0:
                x, y = isc.meet(x, (g[0], g[1])), isc.meet(y, (g[2], g[3]))
                if x == isc.EMPTY or y == isc.EMPTY:  # inconsistent fix: let the solver relax
                    x, y, th = self._solve().last()
        else:
            x, y, th = self._solve().last()
        # hth and th are both in the chain's representation of the heading (every hard
        # heading is met inside it by _hard_f): a plain intersection.
        lo, hi = w.lo, w.hi
        return (
            isc.meet(x, (lo[X][-1], hi[X][-1])),
            isc.meet(y, (lo[Y][-1], hi[Y][-1])),
            isc.meet(th, (lo[TH][-1], hi[TH][-1])),
        )

    def solve(self) -> tuple[IV, IV, IV]:
        """Solve the whole window now; returns the latest box."""
        return tuple(IV.of(*v) for v in self._solve().last())  # type: ignore[return-value]

    def current(self) -> tuple[IV, IV, IV]:
        """Box (x, y, theta) of the latest state (theta unwrapped). Hard boxes added
        since the last solve are met directly; the window is re-solved on the next step
        or by :meth:`window_arrays`."""
        return self._latest()

    def window_arrays(self) -> tuple[list[int], IV, IV, IV]:
        s = self._solve()
        a = np.array
        x, y, th = IV(a(s.xl), a(s.xh)), IV(a(s.yl), a(s.yh)), IV(a(s.tl), a(s.th))
        return list(self._w.stamps), x, y, th

    def _solve(self) -> SolutionF:
        if not self._dirty and self._sol is not None:
            return self._sol
        s = None
        if self.scalar_path:
            try:
                s = self._inc.solve(self._w, self._ef)
            except isc.Fallback:
                s = None
        if s is None:
            a = solve_window(self._w.arrays(), self.cfg, self.e)
            bounds = (a.x.lo, a.x.hi, a.y.lo, a.y.hi, a.th.lo, a.th.hi)
            s = SolutionF(
                *(v.tolist() for v in bounds),  # type: ignore[arg-type]
                relaxed=bool(a.relaxed),
                inconsistent_gps=a.inconsistent_gps.tolist(),
            )
        if s.relaxed:
            self.relaxations += 1
        for k in s.inconsistent_gps:
            st = self._w.gps[k][4]  # type: ignore[index]
            if st not in self.dropped_gps:
                self.dropped_gps.append(st)
        self._sol = s
        self._dirty = self._soft = False
        return s


def _floats(v: IV) -> isc.Iv:
    return float(v.lo), float(v.hi)


def _peer_tuples(px: IV, py: IV, rho: IV, beta: IV) -> list[tuple[isc.Iv, ...]] | None:
    """The per-peer float bounds of :meth:`SlidingWindowCP.relative`'s arrays (None if
    their shapes do not broadcast to one axis of peers)."""
    cols = [np.atleast_1d(a).tolist() for v in (px, py, rho, beta) for a in (v.lo, v.hi)]
    n = max(len(c) for c in cols)
    if n == 0 or any(len(c) not in (1, n) or isinstance(c[0], list) for c in cols):
        return None
    cols = [c * n if len(c) == 1 else c for c in cols]
    return [((a, b), (c, d), (e, f), (g, h)) for a, b, c, d, e, f, g, h in zip(*cols, strict=True)]


def _meet(v: IV) -> IV:
    """Intersection of all intervals of an array (a scalar interval)."""
    return IV.of(np.max(v.lo), np.min(v.hi)) if np.ndim(v.lo) else v
