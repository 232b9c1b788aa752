"""Guaranteed localization by interval constraint propagation (ekf-vs-cp.txt eq. (5)),
alone or cooperatively, over a sliding window of past states.

The unknowns are the poses of the last ``window + 1`` steps; the constraints are the
odometry model eq. (1)-(2) between consecutive steps (wheel displacements known within
bounds), the GPS position boxes, the gyro heading intervals, and (cooperative case)
range-bearing measurements to other robots whose own boxes arrive over the bus. The
solver computes the smallest boxes the constraints allow on this decomposition:

1. heading: exact forward-backward chain ``theta[k+1] = theta[k] + dth[k]`` through
   every gyro interval of the window (``localization.chain``);
2. displacements: eq. (2) in interval arithmetic, per step, with the contracted headings;
3. x and y: exact chains through the hard boxes (prior, peer contractions) and the
   q-relaxed chain through the GPS boxes, so up to ``gps_outliers`` wrong fixes in the
   window (a GPS jump outside its stated bound) neither empty nor bias the box; the fixes
   found inconsistent are reported in :attr:`CPLocalizer.dropped_gps`;
4. a vectorised HC4 pass of the odometry contractor over the whole window (positions
   back onto headings and wheel displacements), repeated to a fixpoint.

Later measurements thus tighten earlier boxes (the backward half of each chain), and the
earlier boxes tighten the current one. When a step leaves the window its box becomes a
hard prior of the next one, so nothing learnt is lost and the cost per step is bounded.

Message-level API (what the daemon's pipeline calls)::

    loc = CPLocalizer(CPConfig(...), robot="r1", initial=PoseBox(...) or None)
    loc.feed_odometry(RobotOdometry) -> PoseBox | None   # one step per odometry message
    loc.feed_gyro(GyroSample) -> PoseBox | None           # heading = angle_rad + offset
    loc.feed_gps(GpsFix) -> PoseBox | None                # east_m / north_m
    loc.feed_peer_box(PoseBox) -> None                    # another robot's latest box
    loc.feed_relative(RelativeMeasurement) -> PoseBox | None
    loc.feed(msg) -> PoseBox | None                       # dispatch on the type
    loc.box() -> PoseBox ; loc.window_boxes() -> list[PoseBox]

Array-level API (benches, tests): ``start``, ``step(stamp, dsr, dsl)``,
``gps(stamp, east, north)``, ``heading(stamp, theta)``, ``relative(...)``, ``current()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from localization.chain import chain, relaxed_chain
from localization.contractors import (
    contract_odometry,
    contract_range_bearing,
    fixpoint,
    odometry_displacement,
)
from localization.interval import IV, TWO_PI, align_angle
from localization.odometry import wheels_from_poses
from msgs import (
    GpsFix,
    GyroSample,
    Interval,
    PoseBox,
    RelativeMeasurement,
    RobotOdometry,
)


@dataclass(frozen=True)
class CPConfig:
    """Error bounds (guaranteed, not sigmas) and solver settings."""

    wheelbase_m: float = 0.33
    wheelbase_bound_m: float = 0.0
    wheel_abs_bound_m: float = 0.0005  # per wheel per step
    wheel_rel_bound: float = 0.01  # fraction of the wheel's displacement per step
    gps_bound_m: float = 2.0  # per axis
    gyro_bound_rad: float = math.radians(1.0)
    gyro_drift_bound_radps: float = 0.0  # growth of the gyro bound with time
    gyro_offset_rad: float = 0.0  # map heading = gyro angle + offset
    window: int = 60  # past steps kept (0 = recursive filter)
    gps_outliers: int = 0  # q of the relaxed intersection over the window
    speed_bound_mps: float = 3.0  # to bridge time-stamp differences (own and peers)
    yaw_rate_bound_radps: float = 3.0
    kappa: float = 0.5
    chord: bool = True
    hc4_odometry: bool = False  # also contract headings from the positions (eq. (2) backward)
    iterations: int = 3
    tol: float = 1e-3
    min_gps_mode: int = 2


def _iv(i: Interval) -> IV:
    return IV.of(i.lo, i.hi)


def _interval(lo: float, hi: float) -> Interval:
    return Interval(float(lo), float(hi))


@dataclass
class _Window:
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


class CPLocalizer:
    """Sliding-window interval constraint propagation for one robot (see module doc)."""

    def __init__(
        self, config: CPConfig | None = None, robot: str = "", initial: PoseBox | None = None
    ) -> None:
        self.cfg = config or CPConfig()
        self.robot = robot
        self._w = _Window()
        self._initial = initial
        self._sol: tuple[IV, IV, IV] | None = None
        self._pred: tuple[IV, IV, IV] | None = None
        self._dirty = True
        self._soft = True  # dirty for a reason other than a new hard box
        self._last_odom: RobotOdometry | None = None
        self._gyro_t0: int | None = None
        self.peers: dict[str, PoseBox] = {}
        self.dropped_gps: list[int] = []  # stamps of GPS fixes found inconsistent
        self.skipped: dict[str, int] = {}
        self.relaxations = 0  # solves that needed more than gps_outliers
        self.e = IV.around(self.cfg.wheelbase_m, self.cfg.wheelbase_bound_m)

    # ------------------------------------------------------------------ array level
    @property
    def started(self) -> bool:
        return bool(self._w.stamps)

    def start(
        self, stamp_ns: int, x: IV | None = None, y: IV | None = None, th: IV | None = None
    ) -> None:
        """First state; unknown components default to the whole line."""
        w = self._w
        w.stamps.append(int(stamp_ns))
        for lst, iv in ((w.hx, x), (w.hy, y), (w.hth, th)):
            lst.append([-math.inf, math.inf] if iv is None else [float(iv.lo), float(iv.hi)])
        w.gps.append(None)
        w.dsr.append((0.0, 0.0))
        w.dsl.append((0.0, 0.0))
        self._dirty = self._soft = True

    def step(self, stamp_ns: int, dsr: float, dsl: float) -> None:
        """A new state, ``dsr``/``dsl`` metres of measured wheel travel after the last."""
        if not self.started:
            raise RuntimeError("CPLocalizer.step before start")
        c = self.cfg
        w = self._w
        br = c.wheel_abs_bound_m + c.wheel_rel_bound * abs(dsr)
        bl = c.wheel_abs_bound_m + c.wheel_rel_bound * abs(dsl)
        r, l = IV.around(dsr, br), IV.around(dsl, bl)
        # Solve the finished window once (its smoothed last state seeds the prediction).
        if self._soft or self._sol is None:
            self._solve()
        if len(w.stamps) >= max(c.window, 1) + 1:
            self._slide()
        x0, y0, th0 = self._latest()
        dx, dy, dth = odometry_displacement(
            th0, th0 + (r - l) / self.e, r, l, self.e, c.kappa, c.chord
        )
        w.stamps.append(int(stamp_ns))
        w.hx.append([-math.inf, math.inf])
        w.hy.append([-math.inf, math.inf])
        w.hth.append([-math.inf, math.inf])
        w.gps.append(None)
        w.dsr.append((float(r.lo), float(r.hi)))
        w.dsl.append((float(l.lo), float(l.hi)))
        self._pred = (x0 + dx, y0 + dy, th0 + dth)
        self._dirty = self._soft = True

    def _slide(self) -> None:
        """Drop the oldest state; its knowledge survives as the next state's prior."""
        w = self._w
        if self._soft or self._sol is None:
            self._solve()
        x, y, th = self._sol
        for lst, iv in ((w.hx, x), (w.hy, y), (w.hth, th)):
            lst[1] = [max(lst[1][0], float(iv.lo[1])), min(lst[1][1], float(iv.hi[1]))]
        for lst in (w.stamps, w.hx, w.hy, w.hth, w.gps, w.dsr, w.dsl):
            del lst[0]
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
        cur = lst[-1]
        if angle and math.isfinite(cur[0]) and math.isfinite(cur[1]):
            iv = align_angle(iv, 0.5 * (cur[0] + cur[1]))
        elif angle and self._sol is not None and math.isfinite(float(self._sol[2].lo[-1])):
            iv = align_angle(iv, float(self._sol[2].mid()[-1]))
        cur[0] = max(cur[0], float(iv.lo))
        cur[1] = min(cur[1], float(iv.hi))
        self._dirty = True

    def relative(self, stamp_ns: int, peer_x: IV, peer_y: IV, rho: IV, beta: IV) -> bool:
        """Range ``rho`` and bearing ``beta`` (own body frame) to peers inside the boxes
        ``peer_x x peer_y`` (valid at ``stamp_ns``; arrays of shape (m,) for m peers at
        once). Contracts the latest state; returns False (and changes nothing) if the
        measurements are inconsistent with it."""
        x, y, th = self._latest()
        # A measurement off the state's stamp: the own motion and turn since are bounded.
        age_s = self._age_s(stamp_ns)
        grow = self.cfg.speed_bound_mps * age_s  # own motion between state and measurement
        beta = beta.inflate(self.cfg.yaw_rate_bound_radps * age_s)
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

    def _latest(self) -> tuple[IV, IV, IV]:
        """The latest box without a window solve when possible: the last solution (or
        the one-step prediction from it, met with this step's GPS box unless outliers
        are tolerated) met with the hard boxes added since. Valid, and the window solve
        at the next step (or :meth:`solve`) brings in the smoothing and relaxation."""
        w = self._w
        n = len(w.stamps)
        if self._sol is not None and not self._soft and self._sol[0].lo.shape[0] == n:
            x, y, th = (v[-1] for v in self._sol)
        elif self._pred is not None and self._sol is not None and self._sol[0].lo.shape[0] == n - 1:
            x, y, th = self._pred
            g = w.gps[-1]
            if g is not None and self.cfg.gps_outliers == 0:
                x, y = x & IV.of(g[0], g[1]), y & IV.of(g[2], g[3])
                if bool(x.is_empty() | y.is_empty()):  # inconsistent fix: let the solver relax
                    x, y, th = (v[-1] for v in self._solve())
        else:
            x, y, th = (v[-1] for v in self._solve())
        hx, hy, hth = (IV.of(*lst[-1]) for lst in (w.hx, w.hy, w.hth))
        if math.isfinite(float(hth.lo)) and math.isfinite(float(hth.hi)):
            hth = align_angle(hth, th.mid())
        return x & hx, y & hy, th & hth

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

    # ------------------------------------------------------------------ solver
    def _solve(self) -> tuple[IV, IV, IV]:
        if not self._dirty and self._sol is not None:
            return self._sol
        w, c = self._w, self.cfg
        hx = IV.of(*np.array(w.hx, dtype=float).T)
        hy = IV.of(*np.array(w.hy, dtype=float).T)
        hth = IV.of(*np.array(w.hth, dtype=float).T)
        r = np.array(w.dsr[1:], dtype=float).reshape(-1, 2)
        l = np.array(w.dsl[1:], dtype=float).reshape(-1, 2)
        dsr, dsl = IV.of(r[:, 0], r[:, 1]), IV.of(l[:, 0], l[:, 1])
        has = np.array([g is not None for g in w.gps])
        g = np.array([gg[:4] if gg is not None else (0.0, 0.0, 0.0, 0.0) for gg in w.gps])
        gx, gy = IV.of(g[:, 0], g[:, 1]), IV.of(g[:, 2], g[:, 3])
        e = self.e
        th = chain(hth, (dsr - dsl) / e)
        x, y = hx, hy
        q_used = c.gps_outliers
        consistent = has
        for _ in range(max(1, c.iterations)):
            x_old, y_old, th_old = x, y, th
            dx, dy, _ = odometry_displacement(th[:-1], th[1:], dsr, dsl, e, c.kappa, c.chord)
            xs, ys = chain(hx & x, dx), chain(hy & y, dy)
            q = c.gps_outliers
            while True:
                rx, cx = relaxed_chain(gx, has, dx, q)
                ry, cy = relaxed_chain(gy, has, dy, q)
                nx, ny = chain(xs & rx, dx), chain(ys & ry, dy)
                bad = bool(np.any(nx.is_empty()) or np.any(ny.is_empty()))
                if not bad or q >= int(has.sum()):
                    break
                q += 1
            q_used = max(q_used, q)
            consistent = cx & cy
            x, y = nx, ny
            if c.hc4_odometry and len(w.stamps) > 1:
                x0, y0, th0, x1, y1, th1, _, _ = contract_odometry(
                    x[:-1], y[:-1], th[:-1], x[1:], y[1:], th[1:], dsr, dsl, e, c.kappa, c.chord
                )
                th_c = IV(
                    np.maximum(np.append(th0.lo, -np.inf), np.insert(th1.lo, 0, -np.inf)),
                    np.minimum(np.append(th0.hi, np.inf), np.insert(th1.hi, 0, np.inf)),
                )
                th = chain(th & th_c, (dsr - dsl) / e)
            if (
                _shrink(x_old, x) <= c.tol
                and _shrink(y_old, y) <= c.tol
                and _shrink(th_old, th) <= c.tol
            ):
                break
        if q_used > c.gps_outliers:
            self.relaxations += 1
        for k in np.flatnonzero(has & ~consistent):
            st = w.gps[k][4]
            if st not in self.dropped_gps:
                self.dropped_gps.append(st)
        self._sol = (x, y, th)
        self._dirty = self._soft = False
        return self._sol

    # ------------------------------------------------------------------ messages
    def _pose_box(self, stamp_ns: int, x: IV, y: IV, th: IV) -> PoseBox:
        lo, hi = float(th.lo), float(th.hi)
        if math.isfinite(lo) and math.isfinite(hi):
            k = round(0.5 * (lo + hi) / TWO_PI)
            lo, hi = lo - k * TWO_PI, hi - k * TWO_PI
            lo, hi = float(np.nextafter(lo, -math.inf)), float(np.nextafter(hi, math.inf))
        return PoseBox(
            stamp_ns=int(stamp_ns),
            robot=self.robot,
            x=_interval(float(x.lo), float(x.hi)),
            y=_interval(float(y.lo), float(y.hi)),
            theta=_interval(lo, hi),
        )

    def box(self) -> PoseBox:
        """The current box as a message (theta shifted next to (-pi, pi])."""
        if not self.started:
            raise RuntimeError("no state yet")
        x, y, th = self.current()
        return self._pose_box(self._w.stamps[-1], x, y, th)

    def window_boxes(self) -> list[PoseBox]:
        stamps, x, y, th = self.window_arrays()
        return [self._pose_box(s, x[i], y[i], th[i]) for i, s in enumerate(stamps)]

    def _skip(self, why: str) -> None:
        self.skipped[why] = self.skipped.get(why, 0) + 1

    def _ensure_started(self, stamp_ns: int) -> None:
        if self.started:
            return
        b = self._initial
        if b is None:
            self.start(stamp_ns)
        else:
            self.start(stamp_ns, _iv(b.x), _iv(b.y), _iv(b.theta))

    def feed_odometry(self, odom: RobotOdometry) -> PoseBox | None:
        """One step per odometry message; wheel travel from the change of the odometry
        pose (inverse of eq. (1)-(2))."""
        prev, self._last_odom = self._last_odom, odom
        if prev is None:
            self._ensure_started(odom.stamp_ns)
            return self.box()
        if odom.stamp_ns <= prev.stamp_ns:
            self._skip("odometry_out_of_order")
            self._last_odom = prev
            return None
        dsr, dsl = wheels_from_poses(
            prev.pose, odom.pose, self.cfg.wheelbase_m, self.cfg.kappa, self.cfg.chord
        )
        if not (math.isfinite(dsr) and math.isfinite(dsl)):
            self._skip("odometry_invalid")
            return None
        self.step(odom.stamp_ns, dsr, dsl)
        return self.box()

    def feed_gyro(self, g: GyroSample) -> PoseBox | None:
        if not self.started or not math.isfinite(g.angle_rad):
            self._skip("gyro_before_start" if self.started is False else "gyro_invalid")
            return None
        if self._gyro_t0 is None:
            self._gyro_t0 = g.stamp_ns
        c = self.cfg
        bound = c.gyro_bound_rad + c.gyro_drift_bound_radps * abs(g.stamp_ns - self._gyro_t0) * 1e-9
        self.heading(g.stamp_ns, IV.around(g.angle_rad + c.gyro_offset_rad, bound))
        return self.box()

    def feed_gps(self, fix: GpsFix) -> PoseBox | None:
        if fix.east_m is None or fix.north_m is None or fix.mode < self.cfg.min_gps_mode:
            self._skip("gps_no_fix")
            return None
        if not (math.isfinite(fix.east_m) and math.isfinite(fix.north_m)):
            self._skip("gps_invalid")
            return None
        self._ensure_started(fix.stamp_ns)
        self.gps(fix.stamp_ns, fix.east_m, fix.north_m)
        return self.box()

    def feed_peer_box(self, box: PoseBox) -> None:
        """Keep another robot's latest box (with its stamp) for relative measurements."""
        if box.robot == self.robot:
            return
        old = self.peers.get(box.robot)
        if old is None or box.stamp_ns >= old.stamp_ns:
            self.peers[box.robot] = box

    def drop_peer(self, robot: str) -> None:
        """Forget a peer (it left the fleet): carry on with the own sensors."""
        self.peers.pop(robot, None)

    def feed_relative(self, m: RelativeMeasurement) -> PoseBox | None:
        return self.feed_relatives([m])

    def feed_relatives(self, ms: list[RelativeMeasurement]) -> PoseBox | None:
        """Range-bearing measurements to several peers at once (vectorised), each used
        with that peer's latest box widened by ``speed_bound * |stamp difference|``."""
        if not self.started:
            self._skip("relative_before_start")
            return None
        use = []
        for m in ms:
            peer = self.peers.get(m.target)
            if peer is None or peer.x.empty or peer.y.empty:
                self._skip("relative_no_peer_box")
                continue
            vals = (m.range_m, m.bearing_rad, m.range_bound_m, m.bearing_bound_rad)
            if (
                not all(math.isfinite(v) for v in vals)
                or m.range_bound_m < 0
                or m.bearing_bound_rad < 0
            ):
                self._skip("relative_invalid")
                continue
            use.append((m, peer))
        if not use:
            return None
        c, now = self.cfg, self._w.stamps[-1]
        # Peer box -> measurement time (peer's motion), measurement -> state time (own).
        dt_peer = np.array([abs(m.stamp_ns - p.stamp_ns) * 1e-9 for m, p in use])
        dt_own = np.array([abs(m.stamp_ns - now) * 1e-9 for m, _ in use])
        grow = c.speed_bound_mps * (dt_peer + dt_own)
        px = IV.of([p.x.lo for _, p in use], [p.x.hi for _, p in use]).inflate(grow)
        py = IV.of([p.y.lo for _, p in use], [p.y.hi for _, p in use]).inflate(grow)
        rho = IV.around([m.range_m for m, _ in use], [m.range_bound_m for m, _ in use])
        beta = IV.around([m.bearing_rad for m, _ in use], [m.bearing_bound_rad for m, _ in use])
        beta = beta.inflate(c.yaw_rate_bound_radps * dt_own)
        ok = self.relative(now, px, py, rho, beta)
        return self.box() if ok else None

    def feed(self, msg) -> PoseBox | None:
        """Dispatch a message by type (others are ignored and counted)."""
        if isinstance(msg, RobotOdometry):
            return self.feed_odometry(msg)
        if isinstance(msg, GyroSample):
            return self.feed_gyro(msg)
        if isinstance(msg, GpsFix):
            return self.feed_gps(msg)
        if isinstance(msg, PoseBox):
            self.feed_peer_box(msg)
            return None
        if isinstance(msg, RelativeMeasurement):
            return self.feed_relative(msg)
        self._skip("unhandled_" + type(msg).__name__)
        return None


def _meet(v: IV) -> IV:
    """Intersection of all intervals of an array (a scalar interval)."""
    return IV.of(np.max(v.lo), np.min(v.hi)) if np.ndim(v.lo) else v


def _shrink(a: IV, b: IV) -> float:
    wa, wb = a.width(), b.width()
    fin = np.isfinite(wa) & np.isfinite(wb)
    if not np.any(fin):
        return 0.0 if np.all(np.isinf(wb) == np.isinf(wa)) else 1.0
    return float(np.max((wa[fin] - wb[fin]) / np.maximum(wa[fin], 1e-12), initial=0.0))
