"""Increments between messages: odometry pose deltas and gyro angle deltas.

Both fusion filters work on what happened *between* two odometry messages:

- :class:`OdometryDeltas` turns successive ``RobotOdometry`` poses (the robot's own
  dead-reckoned pose in the ``odom`` frame) into a step ``(ds, dtheta)``: ``dtheta`` the
  wrapped heading change, ``ds`` the signed chord length (for a constant-curvature step the
  chord points along theta + dtheta / 2, which is the midpoint motion model of
  fusion.models). The first message only sets the baseline; a message not newer than the
  last one is counted (``out_of_order``) and skipped; a step faster than physically
  possible (odometry reset, bad packet), or a stamp more than a second older than the
  last confirmed by the next (a clock set back, msgs.stamps), is counted (``jumps``) and
  re-baselined.
- :class:`GyroDeltas` accumulates the gyro's angle change from ``GyroSample.angle_rad``
  differences (wrapped, so an unwrapped or a wrapped angle both work) until the filter
  takes it at the next odometry step, so gyro and odometry may run at any rates. A
  difference implying more than ``max_rate_radps`` (the device re-zeroed its angle, a
  reconnect) is counted (``discontinuities``) and replaced by rate x dt; a stamp more than
  a second older than the last, confirmed by the next (a clock set back), is counted
  there too and re-baselined. Samples sharing
  one stamp (packets read together after a stall, all stamped with the read time) are
  kept, each change checked against ``max_rate_radps`` x max(dt, ``min_period_s``):
  the device's angle is cumulative, so their rotation is real even if their stamps are not.

Pure bookkeeping: no clocks, times come from the message stamps (integer ns).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from msgs import GyroSample, RobotOdometry, wrap_angle
from msgs.stamps import SetBackGate

NS = 1e-9


@dataclass(frozen=True, slots=True)
class OdometryStep:
    """Motion between two odometry messages: signed distance (m), heading change (rad)."""

    t0_ns: int
    t1_ns: int
    ds_m: float
    dtheta_rad: float
    moving: bool = True

    @property
    def dt_s(self) -> float:
        return (self.t1_ns - self.t0_ns) * NS

    @property
    def at_rest(self) -> bool:
        """No encoder motion at all and the firmware says not moving."""
        return self.ds_m == 0.0 and self.dtheta_rad == 0.0 and not self.moving


class OdometryDeltas:
    """Successive RobotOdometry -> OdometryStep (see module docstring)."""

    def __init__(self, max_speed_mps: float = 3.0, max_rate_radps: float = 4.0 * math.pi):
        self.max_speed_mps = max_speed_mps
        self.max_rate_radps = max_rate_radps
        self.last: RobotOdometry | None = None
        self.messages = 0
        self.out_of_order = 0
        self.jumps = 0
        self._gate = SetBackGate()
        self.baselined = False  # the last feed set a new baseline (first message or jump)

    def reset(self) -> None:
        self.last = None

    def feed(self, msg: RobotOdometry) -> OdometryStep | None:
        """The step since the previous message, or None (first, out of order, jump)."""
        self.messages += 1
        prev = self.last
        self.baselined = False
        if prev is None:
            self.last = msg
            self.baselined = True
            return None
        if msg.stamp_ns <= prev.stamp_ns:
            if self._gate.older(msg.stamp_ns, prev.stamp_ns) == "confirmed":
                self.jumps += 1  # the clock was set back: a new baseline
                self.last = msg
                self.baselined = True
                return None
            self.out_of_order += 1  # late, or a first one more than a second back (held)
            return None
        self._gate.newer()
        self.last = msg
        p0, p1 = prev.pose, msg.pose
        dth = wrap_angle(p1.theta - p0.theta)
        dx, dy = p1.x - p0.x, p1.y - p0.y
        chord = math.hypot(dx, dy)
        dt = (msg.stamp_ns - prev.stamp_ns) * NS
        # Slack of 5 cm / 0.1 rad absorbs quantisation and stamp jitter on short steps.
        if chord > self.max_speed_mps * dt + 0.05 or abs(dth) > self.max_rate_radps * dt + 0.1:
            self.jumps += 1
            self.baselined = True
            return None
        mid = p0.theta + 0.5 * dth
        along = dx * math.cos(mid) + dy * math.sin(mid)
        ds = -chord if along < 0.0 else chord
        return OdometryStep(prev.stamp_ns, msg.stamp_ns, ds, dth, bool(msg.moving))


@dataclass(frozen=True, slots=True)
class GyroDelta:
    """Gyro angle change (rad, raw: bias not removed) over ``covered_s`` seconds."""

    angle_rad: float
    covered_s: float
    samples: int


class GyroDeltas:
    """Accumulates GyroSample angle differences between two ``take()`` calls."""

    def __init__(self, max_rate_radps: float = 2.0 * math.pi, min_period_s: float = 0.005):
        self.max_rate_radps = max_rate_radps
        self.min_period_s = min_period_s
        self.last: GyroSample | None = None
        self.messages = 0
        self.out_of_order = 0
        self.discontinuities = 0
        self._gate = SetBackGate()
        self._sum = 0.0
        self._covered = 0.0
        self._n = 0

    def reset(self) -> None:
        self.last = None
        self.take()

    @property
    def last_stamp_ns(self) -> int | None:
        return None if self.last is None else self.last.stamp_ns

    def feed(self, msg: GyroSample) -> None:
        self.messages += 1
        prev = self.last
        if prev is None:
            self.last = msg
            return
        if msg.stamp_ns < prev.stamp_ns:
            if self._gate.older(msg.stamp_ns, prev.stamp_ns) == "confirmed":
                self.discontinuities += 1  # the clock was set back: a new baseline
                self.last = msg
                return
            self.out_of_order += 1  # late, or a first one more than a second back (held)
            return
        self._gate.newer()
        self.last = msg
        dt = (msg.stamp_ns - prev.stamp_ns) * NS
        d = wrap_angle(msg.angle_rad - prev.angle_rad)
        if not math.isfinite(d) or abs(d) > self.max_rate_radps * max(dt, self.min_period_s) + 1e-3:
            self.discontinuities += 1
            rate = msg.rate_radps if math.isfinite(msg.rate_radps) else 0.0
            d = max(-self.max_rate_radps, min(self.max_rate_radps, rate)) * dt
        self._sum += d
        self._covered += dt
        self._n += 1

    def take(self) -> GyroDelta | None:
        """The accumulated change since the last take (None if no new sample), and reset."""
        out = None if self._n == 0 else GyroDelta(self._sum, self._covered, self._n)
        self._sum, self._covered, self._n = 0.0, 0.0, 0
        return out


MAX_REST_INTERVAL_S = 2.0
"""The longest gyro interval at rest that counts for the bias: a longer one is a gap in
the samples or stamps that stepped forward (the host's clock set forward at boot, by NTP),
over which the angle's change divided by the stamps' interval is not the rate."""


class RestBias:
    """Gyro bias learnt while the robot stands still (zero-velocity calibration).

    Each rest interval's mean rate is blended in with weight dt / T, T the rest time seen
    so far capped at ``window_s``: a plain mean at first, an exponential forgetting mean
    over ``window_s`` later (the bias wanders). Only intervals after ``min_rest_s`` of
    continuous rest count, so the slow end of a manoeuvre is not taken for bias.
    """

    def __init__(self, window_s: float = 30.0, min_rest_s: float = 0.5):
        self.window_s = window_s
        self.min_rest_s = min_rest_s
        self.bias_radps = 0.0
        self.rest_s = 0.0
        self._streak_s = 0.0

    def observe(self, step: OdometryStep, gyro: GyroDelta | None) -> None:
        if not step.at_rest:
            self._streak_s = 0.0
            return
        self._streak_s += step.dt_s
        if gyro is None or gyro.covered_s <= 0.0 or self._streak_s < self.min_rest_s:
            return
        if gyro.covered_s > MAX_REST_INTERVAL_S:
            return  # a gap, or stamps that stepped forward: the mean rate over it is not the bias
        self.rest_s = min(self.rest_s + gyro.covered_s, self.window_s)
        w = min(gyro.covered_s / self.rest_s, 1.0)
        self.bias_radps += w * (gyro.angle_rad / gyro.covered_s - self.bias_radps)
