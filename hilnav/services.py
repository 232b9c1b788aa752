"""The services the pipeline runs, each behind one small adapter: ``feed(topic, msg)``.

An adapter turns the device messages it needs into the calls of one pure service and
returns ``(topic, msg)`` outputs; it keeps no clock (time = message stamps) and no
threads, so the same input gives the same output (replay relies on it).

- :class:`HeadingAdapter`: encoder + gyro heading (ir-grid-mapping eq. 1-4). Uses the
  fusion package's heading filter when it is there; until then :class:`InterimHeading`,
  a minimal version of the same equations, so mapping can run (the hook is
  :func:`make_heading`).
- :class:`InterimPose`: a PoseEstimate from the heading filter (source "heading") until
  the fusion pose EKF (ekf-vs-cp eq. 1-4) is wired in :func:`make_pose`.
- :class:`MappingAdapter`: IR occupancy grid (eq. 5-6) with or without sample-based data
  association (eq. 7-8), fed the latest HeadingEstimate and each IrScan; the map is
  output at most every ``publish_every_s`` of message time.
- :func:`make_localization`: the CP localizer (pose boxes) when the localization package
  offers one; None until then.
"""

from __future__ import annotations

import importlib.util
import math
from typing import Any

import numpy as np

from hilnav.config import RobotConfig
from mapping.association import AssociationConfig, SampleAssociation
from mapping.export import to_grid_msg
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import InverseModelConfig, IrInverseModel, beams_from_scan
from msgs import (
    GyroSample,
    HeadingEstimate,
    IrScan,
    Pose2D,
    PoseEstimate,
    RobotOdometry,
    wrap_angle,
)

Outputs = list[tuple[str, Any]]


def _has(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        return False


class InterimHeading:
    """Encoder + gyro heading Kalman filter, ir-grid-mapping eq. 1-4 (interim version).

    Per odometry step: the encoder's heading change u_enc with variance
    sigma_w^2 = (alpha dd)^2 + (beta du_enc)^2 (eq. 2) is corrected by the gyro's heading
    change over the same interval, variance (gamma du_gyro)^2 (eq. 3-4); the fused
    heading's variance grows by the fused increment's variance. The position follows the
    encoder distance along the fused heading. The gyro's bias is re-estimated whenever
    the odometry says the robot stands still (zero-velocity update), so the turn-on bias
    of a cheap gyro does not become heading drift.
    """

    MIN_BIAS_SAMPLES = 50  # standstill samples before the bias estimate is used

    def __init__(self, cfg: RobotConfig) -> None:
        n = cfg.noise
        self.alpha = n.encoder_alpha_rad_per_m
        self.beta = n.encoder_beta
        self.gamma = n.gyro_gamma
        self.gyro_noise = n.gyro_noise_radps_rthz
        x, y, yaw_deg = cfg.initial_pose
        self.pose = Pose2D(x, y, wrap_angle(math.radians(yaw_deg)))
        self.var = math.radians(0.1) ** 2
        self._odo: RobotOdometry | None = None
        self._gyro_stamp: int | None = None
        self._gyro_angle = 0.0  # the device's angle, bias-corrected
        self._gyro_raw = 0.0
        self._gyro_at_odo: float | None = None
        self._bias = 0.0
        self._bias_n = 0
        self._still = False

    def feed(self, topic: str, msg: Any) -> Outputs:
        if isinstance(msg, GyroSample):
            self._gyro(msg)
            return []
        if isinstance(msg, RobotOdometry):
            est = self._odometry(msg)
            return [("heading", est)] if est is not None else []
        return []

    def _gyro(self, g: GyroSample) -> None:
        if not (math.isfinite(g.rate_radps) and math.isfinite(g.angle_rad)):
            return
        if self._still and abs(g.rate_radps) < math.radians(2.0):
            self._bias_n = min(self._bias_n + 1, 2000)
            self._bias += (g.rate_radps - self._bias) / self._bias_n
        if self._gyro_stamp is not None:
            dt = (g.stamp_ns - self._gyro_stamp) * 1e-9
            # the device integrates its own angle; remove the bias it integrated too
            bias = self._bias if self._bias_n >= self.MIN_BIAS_SAMPLES else 0.0
            self._gyro_angle += (g.angle_rad - self._gyro_raw) - bias * max(dt, 0.0)
        self._gyro_raw = g.angle_rad
        self._gyro_stamp = g.stamp_ns

    def _odometry(self, o: RobotOdometry) -> HeadingEstimate | None:
        prev = self._odo
        self._odo = o
        still = abs(o.linear_vel_mps) < 1e-6 and abs(o.angular_vel_radps) < 1e-6
        self._still = still and prev is not None and not prev.moving and not o.moving
        gyro_now = self._gyro_angle if self._gyro_stamp is not None else None
        gyro_prev, self._gyro_at_odo = self._gyro_at_odo, gyro_now
        if prev is None:
            return HeadingEstimate(o.stamp_ns, self.pose.theta, self.var, self.pose)
        p0, p1 = prev.pose, o.pose
        dx, dy = p1.x - p0.x, p1.y - p0.y
        dd = dx * math.cos(p0.theta) + dy * math.sin(p0.theta)
        du_enc = wrap_angle(p1.theta - p0.theta)
        sw2 = (self.alpha * dd) ** 2 + (self.beta * du_enc) ** 2 + 1e-12
        du_gyro = gyro_now - gyro_prev if gyro_now is not None and gyro_prev is not None else None
        if du_gyro is not None and abs(du_gyro - du_enc) > 0.5:
            du_gyro = None  # the gyro was reset or reconnected in between: encoder only
        if du_gyro is not None:
            dt = max((o.stamp_ns - prev.stamp_ns) * 1e-9, 0.0)
            sg2 = (self.gamma * du_gyro) ** 2 + self.gyro_noise**2 * dt + 1e-12
            k = sw2 / (sw2 + sg2)
            u = du_enc + k * (du_gyro - du_enc)
            self.var += sw2 * (1.0 - k)
        else:
            u = du_enc
            self.var += sw2
        mid = self.pose.theta + 0.5 * u
        th = wrap_angle(self.pose.theta + u)
        self.pose = Pose2D(self.pose.x + dd * math.cos(mid), self.pose.y + dd * math.sin(mid), th)
        return HeadingEstimate(o.stamp_ns, th, self.var, self.pose)


class InterimPose:
    """PoseEstimate from the heading filter's pose (until the fusion pose EKF is wired).

    Position variance grows with the distance driven (encoder_sigma_m_per_m per metre)
    and with the heading variance times the distance squared.
    """

    def __init__(self, cfg: RobotConfig) -> None:
        self.k = cfg.noise.encoder_sigma_m_per_m
        self._last: Pose2D | None = None
        self._var_xy = 0.0

    def feed(self, topic: str, msg: Any) -> Outputs:
        if topic != "heading" or not isinstance(msg, HeadingEstimate):
            return []
        p = msg.pose
        if self._last is not None:
            d = math.hypot(p.x - self._last.x, p.y - self._last.y)
            self._var_xy += (self.k**2) * d + msg.variance_rad2 * d * d
        self._last = p
        v = self._var_xy
        cov = (v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, msg.variance_rad2)
        return [("pose", PoseEstimate(msg.stamp_ns, p, cov, "map", "heading"))]


def make_heading(cfg: RobotConfig) -> Any:
    """The heading service. Hook: fusion's heading filter replaces the interim one here."""
    return InterimHeading(cfg)


def make_pose(cfg: RobotConfig) -> Any:
    """The pose service. Hook: fusion's pose EKF replaces the interim one here."""
    return InterimPose(cfg)


def make_localization(cfg: RobotConfig) -> Any | None:
    """The CP localizer adapter, or None while the localization package has none."""
    if not _has("localization.cp"):
        return None
    return None  # hook: wire localization's CP localizer once it is on main


class MappingAdapter:
    """IR grid mapping fed HeadingEstimate + IrScan; map output throttled by stamp."""

    def __init__(self, cfg: RobotConfig) -> None:
        m = cfg.services.mapping
        self.mounts = np.asarray(cfg.geometry.ir_mounts_rad(), dtype=float)
        self.grid_config = GridConfig(
            resolution_m=m.resolution_m, origin_m=m.origin_m, size_m=m.size_m
        )
        self.period_ns = int(m.publish_every_s * 1e9)
        self.association = m.association
        self.heading: HeadingEstimate | None = None
        self.scans = 0
        self.mismatched = 0
        self._last_map_ns: int | None = None
        if m.association:
            self.da: SampleAssociation | None = SampleAssociation(
                self.mounts,
                AssociationConfig(samples=m.samples),
                self.grid_config,
                InverseModelConfig(),
                seed=m.seed,
            )
            self._grid: OccupancyGrid | None = None
        else:
            self.da = None
            self._grid = OccupancyGrid(self.grid_config)
            self._model = IrInverseModel(InverseModelConfig())

    @property
    def grid(self) -> OccupancyGrid:
        return self.da.grid if self.da is not None else self._grid  # type: ignore[return-value]

    def feed(self, topic: str, msg: Any) -> Outputs:
        if topic == "heading" and isinstance(msg, HeadingEstimate):
            self.heading = msg
            return []
        if not isinstance(msg, IrScan) or self.heading is None:
            return []
        if len(msg.ranges_m) != len(self.mounts):
            self.mismatched += 1
            return []
        self.scans += 1
        out: Outputs = []
        if self.da is not None:
            report = self.da.step(self.heading, msg)
            if report is not None:
                out.append(("association", report))
        else:
            sigma = math.sqrt(max(self.heading.variance_rad2, 0.0))
            self._model.integrate(
                self._grid, beams_from_scan(self.heading.pose, sigma, msg, self.mounts)
            )
        if self._last_map_ns is None or msg.stamp_ns - self._last_map_ns >= self.period_ns:
            self._last_map_ns = msg.stamp_ns
            out.append(("map", self.map_msg(msg.stamp_ns)))
        return out

    def map_msg(self, stamp_ns: int) -> Any:
        return to_grid_msg(self.grid, stamp_ns, "map")
