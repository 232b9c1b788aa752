"""Guaranteed localization by interval constraint propagation (ekf-vs-cp.txt eq. (5)),
alone or cooperatively, over a sliding window of past states: the message-level API and
the peers' boxes.

The unknowns are the poses of the last ``window + 1`` steps; the constraints are the
odometry model eq. (1)-(2) between consecutive steps (wheel displacements known within
bounds), the GPS position boxes, the gyro heading intervals, and (cooperative case)
range-bearing measurements to other robots whose own boxes arrive over the bus.

- ``localization.cp_config``: :class:`CPConfig`, the error bounds and solver settings;
- ``localization.cp_solve``: the window's lists and the contraction of the window on
  interval arrays (heading chain, eq. (2) displacements, x/y chains with the q-relaxed
  GPS, optional HC4): the reference;
- ``localization.cp_incremental``: the same contraction on floats, from what changed
  since the last solve (the daemon's case: one new state per step; bounds at least as
  tight as the reference's, which it falls back to where it does not apply);
- ``localization.cp_window``: the array-level API (states, GPS, headings, position
  boxes, range-bearing to peers; prediction between solves);
- ``localization.cp_scalar``: the one-box contraction against peers on floats (the
  daemon's case, one box per step; fused over ``localization.polar_scalar``; same bounds
  as the array path, which it falls back to); ``SlidingWindowCP.scalar_path = False`` forces the array paths everywhere;
- here: :class:`CPLocalizer`, which turns messages into those calls, keeps the peers'
  latest boxes, and reports boxes as messages.

Message-level API (what the daemon's pipeline calls)::

    loc = CPLocalizer(CPConfig(...), robot="r1", initial=PoseBox(...) or None)
    loc.feed_odometry(RobotOdometry) -> PoseBox | None   # one step per odometry message
    loc.feed_gyro(GyroSample) -> PoseBox | None           # heading = angle_rad + offset
    loc.feed_gps(GpsFix) -> PoseBox | None                # east_m / north_m
    loc.feed_peer_box(PoseBox) -> None                    # another robot's latest box
    loc.feed_relative(RelativeMeasurement) -> PoseBox | None
    loc.feed_relatives(list[RelativeMeasurement]) -> PoseBox | None   # all peers at once
    loc.take_odometry / take_gyro / take_gps / take_relatives -> bool  # the same, no box
    loc.drop_peer(robot)                                  # a peer left: carry on alone
    loc.feed(msg) -> PoseBox | None                       # dispatch on the type
    loc.box() -> PoseBox ; loc.window_boxes() -> list[PoseBox]  # smoothed window
    loc.dropped_gps: list[int]  (stamps of fixes voted out) ; loc.skipped: dict[str, int]

Array-level API (benches, tests): ``start(stamp, x, y, th)``, ``step(stamp, dsr, dsl)``,
``gps(stamp, east, north)``, ``heading(stamp, theta_iv)``, ``position_box(x, y)``,
``relative(stamp, peer_x, peer_y, rho, beta)``, ``current()``, ``solve()``,
``window_arrays()``.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from localization import interval_scalar as isc
from localization.cp_config import CPConfig
from localization.cp_window import SlidingWindowCP
from localization.interval import IV, align_angle
from localization.interval_trig import TWO_PI
from localization.odometry import wheels_from_poses
from msgs import (
    GpsFix,
    GyroSample,
    Interval,
    PoseBox,
    RelativeMeasurement,
    RobotOdometry,
)
from msgs.stamps import SetBackGate

_TWO_PI_HI = math.nextafter(TWO_PI, math.inf)


def _iv(i: Interval) -> IV:
    return IV.of(i.lo, i.hi)


def _interval(lo: float, hi: float) -> Interval:
    return Interval(float(lo), float(hi))


GYRO_GAP_S = 10.0
"""The most one interval between gyro samples adds to the gyro's running time, which its
drift bound grows with: a longer gap is stamps that stepped forward (the host's clock set
forward by NTP, msgs.stamps), not hours of drift; a set back adds nothing."""


class CPLocalizer(SlidingWindowCP):
    """Sliding-window interval constraint propagation for one robot, fed messages (see
    the module doc; the array-level API is :class:`localization.cp_window.SlidingWindowCP`)."""

    FEEDS: ClassVar[dict[type, str]] = {
        RobotOdometry: "feed_odometry",
        GyroSample: "feed_gyro",
        GpsFix: "feed_gps",
        PoseBox: "feed_peer_box",
        RelativeMeasurement: "feed_relative",
    }

    def __init__(
        self, config: CPConfig | None = None, robot: str = "", initial: PoseBox | None = None
    ) -> None:
        super().__init__(config)
        self.robot = robot
        self._initial = initial
        self._last_odom: RobotOdometry | None = None
        self._gyro_last_ns: int | None = None
        self._gyro_run_ns = 0  # the time the gyro has run since its first sample
        self._set_back = SetBackGate()
        self.peers: dict[str, PoseBox] = {}

    def _pose_box(self, stamp_ns: int, x: IV, y: IV, th: IV) -> PoseBox:
        if math.isfinite(float(th.lo)) and math.isfinite(float(th.hi)):
            th = align_angle(th, 0.0)  # shifted by an enclosure of 2*pi*k: still guaranteed
        lo, hi = float(th.lo), float(th.hi)
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
        if not self.scalar_path:
            x, y, th = self.current()
            return self._pose_box(self._w.stamps[-1], x, y, th)
        (xl, xh), (yl, yh), (tl, th_) = self._latest_f()
        if math.isfinite(tl) and math.isfinite(th_):  # align_angle(th, 0.0) on floats
            k = float(round((0.0 - (0.5 * tl + 0.5 * th_)) / TWO_PI))
            if k != 0.0:
                tl, th_ = isc.add((tl, th_), isc.mul((k, k), (TWO_PI, _TWO_PI_HI)))
        return PoseBox(
            stamp_ns=int(self._w.stamps[-1]),
            robot=self.robot,
            x=Interval(xl, xh),
            y=Interval(yl, yh),
            theta=Interval(tl, th_),
        )

    def window_boxes(self) -> list[PoseBox]:
        stamps, x, y, th = self.window_arrays()
        return [self._pose_box(s, x[i], y[i], th[i]) for i, s in enumerate(stamps)]

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
        return self.box() if self.take_odometry(odom) else None

    def feed_gyro(self, g: GyroSample) -> PoseBox | None:
        return self.box() if self.take_gyro(g.stamp_ns, g.angle_rad) else None

    def feed_gps(self, fix: GpsFix) -> PoseBox | None:
        return self.box() if self.take_gps(fix) else None

    # The feeds without the box: True where the state changed (the box is then ``box()``).
    def take_odometry(self, odom: RobotOdometry) -> bool:
        """:meth:`feed_odometry` without the box."""
        prev, self._last_odom = self._last_odom, odom
        if prev is None:
            self._ensure_started(odom.stamp_ns)
            return True
        if odom.stamp_ns <= prev.stamp_ns:
            if self._set_back.older(odom.stamp_ns, prev.stamp_ns) == "confirmed":
                self._skip("odometry_clock_set_back")  # a new baseline
                return False
            self._skip("odometry_out_of_order")  # late, or held: one more than a second back
            self._last_odom = prev
            return False
        self._set_back.newer()
        dsr, dsl = wheels_from_poses(
            prev.pose, odom.pose, self.cfg.wheelbase_m, self.cfg.kappa, self.cfg.chord
        )
        if not (math.isfinite(dsr) and math.isfinite(dsl)):
            self._skip("odometry_invalid")
            return False
        self.step(odom.stamp_ns, dsr, dsl)
        return True

    def take_gyro(self, stamp_ns: int, angle_rad: float) -> bool:
        """:meth:`feed_gyro` of a sample's stamp and angle, without the box."""
        if not self.started or not math.isfinite(angle_rad):
            self._skip("gyro_before_start" if self.started is False else "gyro_invalid")
            return False
        last, self._gyro_last_ns = self._gyro_last_ns, stamp_ns
        if last is not None:  # the gyro's running time: a step of the stamps is not time
            self._gyro_run_ns += min(max(stamp_ns - last, 0), int(GYRO_GAP_S * 1e9))
        c = self.cfg
        bound = c.gyro_bound_rad + c.gyro_drift_bound_radps * self._gyro_run_ns * 1e-9
        self.heading_f(stamp_ns, *isc.around(angle_rad + c.gyro_offset_rad, bound))
        return True

    def take_gps(self, fix: GpsFix) -> bool:
        """:meth:`feed_gps` without the box."""
        en = self._gps_position(fix, self.cfg.min_gps_mode)
        if en is None:
            return False
        self._ensure_started(fix.stamp_ns)
        self.gps(fix.stamp_ns, *en)
        return True

    @property
    def stamp_ns(self) -> int:
        """Stamp of the latest state (that of :meth:`box`)."""
        return int(self._w.stamps[-1])

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
        return self.box() if self.take_relatives(ms) else None

    def take_relatives(self, ms: list[RelativeMeasurement]) -> bool:
        """:meth:`feed_relatives` without the box."""
        if not self.started:
            self._skip("relative_before_start")
            return False
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
            return False
        c, now = self.cfg, self._w.stamps[-1]
        if self.scalar_path and self._relatives_f(use, now):
            return True
        # Peer box -> measurement time (peer's motion), measurement -> state time (own).
        dt_peer = np.array([abs(m.stamp_ns - p.stamp_ns) * 1e-9 for m, p in use])
        dt_own = np.array([abs(m.stamp_ns - now) * 1e-9 for m, _ in use])
        grow = c.speed_bound_mps * (dt_peer + dt_own)
        px = IV.of([p.x.lo for _, p in use], [p.x.hi for _, p in use]).inflate(grow)
        py = IV.of([p.y.lo for _, p in use], [p.y.hi for _, p in use]).inflate(grow)
        rho = IV.around([m.range_m for m, _ in use], [m.range_bound_m for m, _ in use])
        beta = IV.around([m.bearing_rad for m, _ in use], [m.bearing_bound_rad for m, _ in use])
        beta = beta.inflate(c.yaw_rate_bound_radps * dt_own)
        return self.relative(now, px, py, rho, beta)

    def _relatives_f(self, use: list[tuple[RelativeMeasurement, PoseBox]], now: int) -> bool:
        """:meth:`feed_relatives`' boxes as floats, through the scalar path
        (:meth:`SlidingWindowCP.relative_f`); False where it does not apply."""
        c, peers = self.cfg, []
        for m, p in use:
            dt_own = abs(m.stamp_ns - now) * 1e-9
            grow = c.speed_bound_mps * (abs(m.stamp_ns - p.stamp_ns) * 1e-9 + dt_own)
            rho = isc.around(m.range_m, m.range_bound_m)
            beta = isc.inflate(
                isc.around(m.bearing_rad, m.bearing_bound_rad), c.yaw_rate_bound_radps * dt_own
            )
            px = isc.inflate((p.x.lo, p.x.hi), grow)
            py = isc.inflate((p.y.lo, p.y.hi), grow)
            peers.append((px, py, rho, beta))
        return bool(self.relative_f(now, peers))
