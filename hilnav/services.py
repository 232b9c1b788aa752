"""The services the pipeline runs, each behind one small adapter: ``feed(topic, msg)``.

An adapter turns the device messages it needs into the message-level calls of one pure
service and returns ``(topic, msg)`` outputs; it keeps no clock (time = message stamps)
and no threads, so the same input gives the same output (replay relies on it).

- :class:`HeadingAdapter`: fusion.heading.HeadingFilter, encoder + gyro heading
  (ir-grid-mapping eq. 1-4) -> ``heading`` at every odometry message.
- :class:`PoseAdapter`: fusion.pose_ekf.PoseEkf, odometry + gyro + GPS (ekf-vs-cp eq.
  1-4) -> ``pose`` (frame "map") at every odometry message.
- :class:`LocalizationAdapter`: localization.cp.CPLocalizer, guaranteed boxes (ekf-vs-cp
  eq. 5) from bounded odometry, gyro and GPS errors, plus the other robots' boxes ->
  ``pose_box``, at most every ``publish_every_s`` of message time. The gyro is given to
  it once per odometry step (its latest sample), not at 100 Hz: each sample re-solves
  the window.
- :class:`MappingAdapter`: IR occupancy grid (eq. 5-6) with or without sample-based data
  association (eq. 7-8), fed the latest HeadingEstimate and each IrScan -> ``map`` at
  most every ``publish_every_s`` of message time, and ``association`` reports.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fusion.heading import HeadingFilter, HeadingParams
from fusion.pose_ekf import PoseEkf, PoseEkfParams
from hilnav.config import RobotConfig
from localization.cp import CPConfig, CPLocalizer
from mapping.association import AssociationConfig, SampleAssociation
from mapping.export import to_grid_msg
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import InverseModelConfig, IrInverseModel, beams_from_scan
from msgs import (
    GpsFix,
    GyroSample,
    HeadingEstimate,
    Interval,
    IrScan,
    Pose2D,
    PoseBox,
    RobotOdometry,
    wrap_angle,
)

Outputs = list[tuple[str, Any]]


def initial_pose(cfg: RobotConfig) -> Pose2D:
    x, y, yaw_deg = cfg.initial_pose
    return Pose2D(x, y, wrap_angle(math.radians(yaw_deg)))


class GyroRestamp:
    """Strictly increasing gyro stamps, at least a quarter of the nominal period apart.

    The stream drivers stamp every message decoded from one read with that read's time,
    so two gyro packets that arrived together share a stamp, or come microseconds apart.
    fusion.increments.GyroDeltas drops a sample whose stamp is not newer, and takes an
    angle change that is large for a tiny interval for a discontinuity (and replaces it
    by rate x dt), which loses real rotation. Spacing such samples a quarter period apart
    keeps every angle difference with a plausible interval (the restamped times catch up
    with the real ones at the next gap); the angles themselves are untouched. Deterministic: depends only on the input sequence.
    """

    def __init__(self, rate_hz: float) -> None:
        self.spacing_ns = int(0.25e9 / rate_hz)
        self._last: int | None = None

    def __call__(self, g: GyroSample) -> GyroSample:
        last = self._last
        if last is not None and g.stamp_ns < last + self.spacing_ns:
            if g.stamp_ns < last - 1_000_000_000:
                self._last = g.stamp_ns  # a real jump back (clock set): follow it
                return g
            g = GyroSample(last + self.spacing_ns, g.rate_radps, g.angle_rad, g.angle_wrapped_rad)
        self._last = g.stamp_ns
        return g


class GyroFirst:
    """Feeds a filter the gyro samples of an interval before the odometry that ends it.

    Messages reach the pipeline in arrival order; after a stall (a busy machine) a burst
    of SIPs and a burst of gyro packets arrive, each burst with one late stamp, in either
    order. The fusion filters fuse the gyro's change *between two odometry messages* with
    the encoders' change over the same interval, so the intervals must match:

    - an odometry message is held until a gyro sample strictly newer arrives (every gyro
      sample up to its time has then been given) or a newer odometry message does (the
      gyro is silent: carry on without it);
    - of several odometry messages with the same stamp (SIPs read together) only the last
      is kept: odometry poses are cumulative, so it covers the whole burst;
    - odometry older than the last one released is dropped (counted).

    Costs at most one gyro period of latency. Deterministic: depends only on the input
    sequence.
    """

    def __init__(self) -> None:
        self.held: RobotOdometry | None = None
        self._released: int | None = None
        self.dropped = 0

    def _release(self) -> list[RobotOdometry]:
        h, self.held = self.held, None
        if h is None:
            return []
        if self._released is not None and h.stamp_ns <= self._released:
            self.dropped += 1
            return []
        self._released = h.stamp_ns
        return [h]

    def gyro(self, g: GyroSample) -> list[RobotOdometry]:
        """Odometry to feed before this gyro sample."""
        if self.held is not None and g.stamp_ns > self.held.stamp_ns:
            return self._release()
        return []

    def odometry(self, o: RobotOdometry) -> list[RobotOdometry]:
        """Odometry to feed now (the held one, if this one is newer)."""
        h = self.held
        if h is not None and o.stamp_ns < h.stamp_ns:
            self.dropped += 1
            return []
        out = self._release() if h is not None and o.stamp_ns > h.stamp_ns else []
        self.held = o
        if h is not None and o.stamp_ns == h.stamp_ns:
            self.dropped += 1  # the earlier one of a burst: replaced by this one
        return out


class HeadingAdapter:
    """fusion.heading.HeadingFilter fed odometry and gyro -> ``heading``."""

    def __init__(self, cfg: RobotConfig) -> None:
        n = cfg.noise
        params = HeadingParams(
            alpha_rad_per_m=n.encoder_alpha_rad_per_m,
            beta=n.encoder_beta,
            gamma=n.gyro_gamma,
            gyro_arw_rad_per_sqrt_s=n.gyro_arw_rad_per_sqrt_s,
            bias_min_rest_s=cfg.services.heading.bias_min_rest_s,
        )
        self.filter = HeadingFilter(params, initial=initial_pose(cfg))
        self.restamp = GyroRestamp(cfg.devices.gyro.rate_hz)
        self.merge = GyroFirst()

    def feed(self, topic: str, msg: Any) -> Outputs:
        if isinstance(msg, GyroSample):
            out = self._odometry(self.merge.gyro(msg))
            self.filter.feed_gyro(self.restamp(msg))
            return out
        if isinstance(msg, RobotOdometry):
            return self._odometry(self.merge.odometry(msg))
        return []

    def _odometry(self, todo: list[RobotOdometry]) -> Outputs:
        out: Outputs = []
        for o in todo:
            est = self.filter.feed_odometry(o)
            if est is not None:
                out.append(("heading", est))
        return out


class PoseAdapter:
    """fusion.pose_ekf.PoseEkf fed odometry, gyro and (optionally) GPS -> ``pose``."""

    def __init__(self, cfg: RobotConfig) -> None:
        n, sv = cfg.noise, cfg.services.pose
        params = PoseEkfParams(
            wheelbase_m=cfg.geometry.wheel_base_m,
            wheel_noise_m_per_sqrt_m=n.wheel_noise_m_per_sqrt_m,
            gyro_gamma=n.gyro_gamma,
            gyro_arw_rad_per_sqrt_s=n.gyro_arw_rad_per_sqrt_s,
            gps_uere_m=n.gps_uere_m,
            gps_lever_m=cfg.geometry.gps_antenna_m,
            bias_min_rest_s=cfg.services.heading.bias_min_rest_s,
            init_from_gps=sv.init_from_gps,
            robot=cfg.name,
        )
        self.use_gps = sv.use_gps
        self.ekf = PoseEkf(params, initial=None if sv.init_from_gps else initial_pose(cfg))
        self.restamp = GyroRestamp(cfg.devices.gyro.rate_hz)
        self.merge = GyroFirst()

    def feed(self, topic: str, msg: Any) -> Outputs:
        if isinstance(msg, GyroSample):
            out = self._odometry(self.merge.gyro(msg))
            self.ekf.feed_gyro(self.restamp(msg))
            return out
        if isinstance(msg, GpsFix):
            if self.use_gps:
                self.ekf.feed_gps(msg)  # the next odometry's pose carries the update
        elif isinstance(msg, RobotOdometry):
            return self._odometry(self.merge.odometry(msg))
        return []

    def _odometry(self, todo: list[RobotOdometry]) -> Outputs:
        out: Outputs = []
        for o in todo:
            est = self.ekf.feed_odometry(o)
            if est is not None:
                out.append(("pose", est))
        return out


class LocalizationAdapter:
    """localization.cp.CPLocalizer -> ``pose_box`` (throttled by message time)."""

    def __init__(self, cfg: RobotConfig) -> None:
        lc = cfg.services.localization
        p0 = initial_pose(cfg)
        self.yaw0 = p0.theta
        config = CPConfig(
            wheelbase_m=cfg.geometry.wheel_base_m,
            wheelbase_bound_m=lc.wheelbase_bound_m,
            wheel_abs_bound_m=lc.wheel_abs_bound_m,
            wheel_rel_bound=lc.wheel_rel_bound,
            gps_bound_m=lc.gps_bound_m,
            # the gyro heading is yaw0 + its turn since start: yaw0's own bound adds in
            gyro_bound_rad=math.radians(lc.gyro_bound_deg + lc.initial_bound_deg),
            gyro_drift_bound_radps=math.radians(lc.gyro_drift_bound_degps),
            gyro_offset_rad=0.0,
            window=lc.window,
            gps_outliers=lc.gps_outliers,
            speed_bound_mps=cfg.cmd_vel.max_linear_mps * 2.0,
            yaw_rate_bound_radps=cfg.cmd_vel.max_angular_radps * 2.0,
        )
        b, bth = lc.initial_bound_m, math.radians(lc.initial_bound_deg)
        box = PoseBox(
            0,
            cfg.name,
            Interval(p0.x - b, p0.x + b),
            Interval(p0.y - b, p0.y + b),
            Interval(p0.theta - bth, p0.theta + bth),
        )
        self.cp = CPLocalizer(config, robot=cfg.name, initial=box)
        self.period_ns = int(lc.publish_every_s * 1e9)
        self._gyro: GyroSample | None = None
        self._gyro0: float | None = None
        self._last_ns: int | None = None

    def feed(self, topic: str, msg: Any) -> Outputs:
        box = None
        if isinstance(msg, GyroSample):
            if math.isfinite(msg.angle_rad):
                if self._gyro0 is None:
                    self._gyro0 = msg.angle_rad
                self._gyro = msg
            return []
        if isinstance(msg, RobotOdometry):
            box = self.cp.feed_odometry(msg)
            g = self._gyro
            if g is not None and self.cp.started and self._gyro0 is not None:
                # map heading = initial yaw + the gyro's turn since its first sample
                angle = self.yaw0 + (g.angle_rad - self._gyro0)
                box = self.cp.feed_gyro(
                    GyroSample(g.stamp_ns, g.rate_radps, angle, g.angle_wrapped_rad)
                )
                self._gyro = None
        elif isinstance(msg, GpsFix):
            box = self.cp.feed_gps(msg)
        if box is None:
            return []
        if self._last_ns is not None and box.stamp_ns - self._last_ns < self.period_ns:
            return []
        self._last_ns = box.stamp_ns
        return [("pose_box", box)]

    def feed_other(self, robot: str, topic: str, msg: Any) -> Outputs:
        """A peer's box (a box that claims another robot than its sender is ignored)."""
        if topic == "pose_box" and isinstance(msg, PoseBox) and msg.robot == robot:
            self.cp.feed_peer_box(msg)
        return []

    def drop_peer(self, robot: str) -> None:
        self.cp.drop_peer(robot)


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
