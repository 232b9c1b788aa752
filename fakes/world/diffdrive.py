"""Ground-truth differential-drive robot with wheel slip and encoder quantisation.

The motors turn the wheels at the commanded wheel speeds (acceleration limits belong to
the emulated firmware, not here). Encoders count wheel *rotation*, quantised to ticks;
the ground moves by the rotation times (1 + slip), where slip per wheel is a fixed
effective-radius error (tyre wear, load) plus white noise whose variance grows with the
distance rolled. The true pose integrates the ground displacements over the true wheel
base, which differs slightly from the nominal one the firmware uses. Those three effects
are what makes encoder-only heading drift (ir-grid-mapping.txt, Table 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from msgs import Pose2D, wrap_angle


@dataclass(frozen=True)
class SlipModel:
    """Wheel/ground error model; every figure is a 1-sigma value.

    radius_error: fixed relative error of each wheel's effective radius, drawn once per
        robot from N(0, radius_error^2).
    slip_per_sqrt_m: relative white slip; a wheel rolling d metres in a step slips by
        N(0, slip_per_sqrt_m^2 * |d|) metres.
    wheelbase_error_m: fixed error of the effective wheel base, drawn once per robot.
    """

    radius_error: float = 0.002
    slip_per_sqrt_m: float = 0.004
    wheelbase_error_m: float = 0.003


@dataclass
class DiffDriveRobot:
    """One simulated robot: true pose, wheel speeds, encoder counters."""

    name: str
    pose: Pose2D = field(default_factory=Pose2D)
    wheelbase_m: float = 0.33
    ticks_per_m: float = 128_000.0
    slip: SlipModel = field(default_factory=SlipModel)
    seed: int = 0
    # State updated by step():
    left_cmd_mps: float = 0.0
    right_cmd_mps: float = 0.0
    left_ticks: int = 0
    right_ticks: int = 0
    yaw_rate_radps: float = 0.0
    speed_mps: float = 0.0
    distance_m: float = 0.0
    stalled: bool = False
    bumped: bool = False

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        s = self.slip
        self._radius_err = self._rng.normal(0.0, s.radius_error, size=2)
        self._true_wheelbase = self.wheelbase_m + self._rng.normal(0.0, s.wheelbase_error_m)
        self._rot = np.zeros(2)  # cumulative wheel rotation in metres of rolled tread

    def command_wheels(self, left_mps: float, right_mps: float) -> None:
        """Set the wheel speeds the motors achieve (m/s of tread)."""
        self.left_cmd_mps = float(left_mps)
        self.right_cmd_mps = float(right_mps)

    def step(self, dt: float) -> None:
        """Advance the truth by ``dt`` seconds."""
        roll = np.array([self.left_cmd_mps, self.right_cmd_mps]) * dt
        if self.stalled:
            roll[:] = 0.0
        noise = self._rng.normal(0.0, self.slip.slip_per_sqrt_m, size=2) * np.sqrt(np.abs(roll))
        ground = roll * (1.0 + self._radius_err) + noise
        self._rot += roll
        self.left_ticks = int(math.floor(self._rot[0] * self.ticks_per_m))
        self.right_ticks = int(math.floor(self._rot[1] * self.ticks_per_m))
        dl, dr = float(ground[0]), float(ground[1])
        d = 0.5 * (dl + dr)
        dth = (dr - dl) / self._true_wheelbase
        th = self.pose.theta
        # Exact arc integration (midpoint heading is exact for constant curvature).
        if abs(dth) > 1e-9:
            r = d / dth
            x = self.pose.x + r * (math.sin(th + dth) - math.sin(th))
            y = self.pose.y - r * (math.cos(th + dth) - math.cos(th))
        else:
            x = self.pose.x + d * math.cos(th)
            y = self.pose.y + d * math.sin(th)
        self.pose = Pose2D(x, y, wrap_angle(th + dth))
        self.yaw_rate_radps = dth / dt if dt > 0 else 0.0
        self.speed_mps = d / dt if dt > 0 else 0.0
        self.distance_m += abs(d)

    def encoder_m(self) -> tuple[float, float]:
        """Cumulative encoder distance of each wheel (left, right) in metres, quantised."""
        return self.left_ticks / self.ticks_per_m, self.right_ticks / self.ticks_per_m
