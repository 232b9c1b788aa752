"""The services the pipeline runs, each behind one small adapter: ``feed(topic, msg)``.

An adapter turns the device messages it needs into the message-level calls of one pure
service and returns ``(topic, msg)`` outputs; it keeps no clock (time = message stamps)
and no threads, so the same input gives the same output (replay relies on it).

- :class:`HeadingAdapter`: fusion.heading.HeadingFilter, encoder + gyro heading
  (ir-grid-mapping eq. 1-4) -> ``heading`` at every odometry message.
- :class:`PoseAdapter`: fusion.pose_ekf.PoseEkf, odometry + gyro + GPS (ekf-vs-cp eq.
  1-4) -> ``pose`` (frame "map") at every odometry message.

  Both filters take the device messages in arrival order, as the stream drivers stamp
  them (a burst read at once shares one stamp): each gets a fusion.arrival.ArrivalOrder,
  and its alignment front end (fusion.alignment) hands it matched gyro/odometry
  intervals. An odometry message's estimate comes out at once when the gyro has caught
  up with it, else at the arrival of the gyro sample that covers it.
- :class:`LocalizationAdapter`: localization.cp.CPLocalizer, guaranteed boxes (ekf-vs-cp
  eq. 5) from bounded odometry, gyro and GPS errors, plus the other robots' boxes and
  this robot's range-bearing scans of them (``relative``, contracted all at once) ->
  ``pose_box``, at most every ``publish_every_s`` of message time. The gyro is given to
  it once per odometry step (its latest sample), not at 100 Hz: each sample re-solves
  the window. A GPS fix goes to the nearer of the latest state and the next one (the
  next odometry step is expected one odometry interval after the latest): a fix nearer
  the next is held and given right after that step, so its box comes out with the step.
- :class:`MappingAdapter`: IR occupancy grid (eq. 5-6) with or without sample-based data
  association (eq. 7-8), fed the latest HeadingEstimate and each IrScan -> ``map`` at
  most every ``publish_every_s`` of message time, and ``association`` reports.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fusion.arrival import ArrivalOrder
from fusion.heading import HeadingFilter, HeadingParams
from fusion.pose_ekf import PoseEkf, PoseEkfParams
from hilnav.config import RobotConfig
from localization.cp import CPConfig, CPLocalizer
from mapping.association import AssociationConfig, SampleAssociation
from mapping.export import to_grid_msg
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import InverseModelConfig, IrInverseModel, beams_from_scan
from mapping.motion_filter import MotionFilter, MotionFilterConfig
from msgs import (
    GpsFix,
    GyroSample,
    HeadingEstimate,
    Interval,
    IrScan,
    Pose2D,
    PoseBox,
    RelativeScan,
    RobotOdometry,
    wrap_angle,
)
from msgs.stamps import set_back

Outputs = list[tuple[str, Any]]


def initial_pose(cfg: RobotConfig) -> Pose2D:
    x, y, yaw_deg = cfg.initial_pose
    return Pose2D(x, y, wrap_angle(math.radians(yaw_deg)))


def heading_params(cfg: RobotConfig) -> HeadingParams:
    """The heading filter's parameters from the robot config."""
    n = cfg.noise
    return HeadingParams(
        alpha_rad_per_m=n.encoder_alpha_rad_per_m,
        beta=n.encoder_beta,
        gamma=n.gyro_gamma,
        gyro_arw_rad_per_sqrt_s=n.gyro_arw_rad_per_sqrt_s,
        encoder_bias_sigma_rad_per_m=n.encoder_bias_sigma_rad_per_m,
        encoder_bias_rad_per_m=n.encoder_bias_rad_per_m,
        track_scale_sigma=n.track_scale_sigma,
        gyro_scale_sigma=n.gyro_scale_sigma,
        gyro_bias_sigma_radps=n.gyro_bias_sigma_radps,
        gyro_bias_walk_radps_per_sqrt_s=n.gyro_bias_walk_radps_per_sqrt_s,
        bias_min_rest_s=cfg.services.heading.bias_min_rest_s,
    )


class HeadingAdapter:
    """fusion.heading.HeadingFilter fed odometry and gyro -> ``heading``."""

    def __init__(self, cfg: RobotConfig) -> None:
        params = heading_params(cfg)
        arrival = ArrivalOrder(cfg.devices.gyro.rate_hz)
        self.filter = HeadingFilter(params, initial=initial_pose(cfg), arrival=arrival)

    def feed(self, topic: str, msg: Any) -> Outputs:
        if isinstance(msg, GyroSample | RobotOdometry):
            est = self.filter.feed(msg)
            return [] if est is None else [("heading", est)]
        return []


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
        initial = None if sv.init_from_gps else initial_pose(cfg)
        arrival = ArrivalOrder(cfg.devices.gyro.rate_hz)
        self.ekf = PoseEkf(params, initial=initial, arrival=arrival)

    def feed(self, topic: str, msg: Any) -> Outputs:
        if isinstance(msg, GpsFix):
            if self.use_gps:
                self.ekf.feed_gps(msg)  # the next odometry's pose carries the update
        elif isinstance(msg, GyroSample | RobotOdometry):
            est = self.ekf.feed(msg)
            return [] if est is None else [("pose", est)]
        return []


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
        self.robot = cfg.name
        self._gyro: GyroSample | None = None
        self._gyro0: float | None = None
        self._last_ns: int | None = None
        self._odom_ns: int | None = None  # stamp of the latest odometry step
        self._odom_dt_ns = 0  # interval between the last two odometry steps
        self._gps: GpsFix | None = None  # a fix held for the next step

    def feed(self, topic: str, msg: Any) -> Outputs:
        if isinstance(msg, GyroSample):
            if math.isfinite(msg.angle_rad):
                if self._gyro0 is None:
                    self._gyro0 = msg.angle_rad
                self._gyro = msg
            return []
        if isinstance(msg, RobotOdometry):
            changed = self._odometry(msg)
        elif isinstance(msg, GpsFix):
            changed = self._fix(msg)
        elif isinstance(msg, RelativeScan) and msg.robot == self.robot and msg.seen:
            changed = self.cp.take_relatives(list(msg.seen))
        else:
            return []
        if not changed:
            return []
        # The box is made only when it is published (the CP state is the same either way).
        stamp = self.cp.stamp_ns
        last = self._last_ns
        if last is not None and stamp - last < self.period_ns and not set_back(stamp, last):
            return []  # within the period (a clock set back starts it again: msgs.stamps)
        self._last_ns = stamp
        return [("pose_box", self.cp.box())]

    def _odometry(self, msg: RobotOdometry) -> bool:
        stepped = self.cp.take_odometry(msg)
        if stepped and self._odom_ns is not None:
            self._odom_dt_ns = msg.stamp_ns - self._odom_ns
        if stepped:
            self._odom_ns = msg.stamp_ns
        changed = stepped
        g = self._gyro
        if g is not None and self.cp.started and self._gyro0 is not None:
            # map heading = initial yaw + the gyro's turn since its first sample
            changed = self.cp.take_gyro(g.stamp_ns, self.yaw0 + (g.angle_rad - self._gyro0))
            self._gyro = None
        held = self._gps
        if held is not None and held.stamp_ns <= msg.stamp_ns:
            self._gps = None
            changed = self.cp.take_gps(held) or changed
        return changed

    def _fix(self, fix: GpsFix) -> bool:
        if self._gps is not None:  # the step it waited for did not come: use it now
            held, self._gps = self._gps, None
            self.cp.take_gps(held)
        if self._odom_ns is not None and 2 * (fix.stamp_ns - self._odom_ns) > self._odom_dt_ns > 0:
            self._gps = fix  # nearer the next odometry step than the latest
            return False
        return self.cp.take_gps(fix)

    def feed_other(self, robot: str, topic: str, msg: Any) -> Outputs:
        """A peer's box (a box that claims another robot than its sender is ignored)."""
        if topic == "pose_box" and isinstance(msg, PoseBox) and msg.robot == robot:
            self.cp.feed_peer_box(msg)
        return []

    def drop_peer(self, robot: str) -> None:
        self.cp.drop_peer(robot)


def association_config(cfg: RobotConfig) -> AssociationConfig:
    """The sample-based data association's parameters from the robot config: its sample
    count, whether its pose graph is solved at the end, and the prior of the heading's drift per radian turned that the association
    tests on the map (the gyro's scale sigma: the one systematic term of the heading
    filter that no sensor on the robot reveals)."""
    m = cfg.services.mapping
    return AssociationConfig(samples=m.samples, drift_sigma_per_rad=cfg.noise.gyro_scale_sigma,
                             pose_graph=m.pose_graph)  # fmt: skip


def motion_filter_config(cfg: RobotConfig) -> MotionFilterConfig:
    """Which scans the grid takes (mapping.motion_filter), from the robot config."""
    m = cfg.services.mapping
    return MotionFilterConfig(m.min_travel_m, math.radians(m.min_turn_deg), m.max_interval_s,
                              m.motion_filter)  # fmt: skip


class MappingAdapter:
    """IR grid mapping fed HeadingEstimate + IrScan; map output throttled by stamp. The
    scans go through the motion filter first (it counts what it leaves out; :meth:`summary`)."""

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
        self.refused = 0  # plain map: scans where the grid may not grow (max_cells)
        self.filter = MotionFilter(motion_filter_config(cfg))
        self._last_map_ns: int | None = None
        self._last_scan_ns: int | None = None
        self.finished = False
        if m.association:
            self.da: SampleAssociation | None = SampleAssociation(
                self.mounts,
                association_config(cfg),
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
        self._last_scan_ns = msg.stamp_ns
        out: Outputs = []
        # A scan taken where the last one was, or with no pose to map it at, is left
        # out (the filter counts it).
        if self.filter.keep(self.heading.pose, msg.stamp_ns):
            if self.da is not None:
                report = self.da.step(self.heading, msg)
                if report is not None:
                    out.append(("association", report))
            else:
                h = self.heading.pose
                pose = np.array([h.x, h.y, h.theta])
                box = self._model.scan_box(pose, self.mounts, self._grid.resolution)
                if self._grid.fits(*box):
                    sigma = math.sqrt(max(self.heading.variance_rad2, 0.0))
                    self._model.integrate(self._grid, beams_from_scan(h, sigma, msg, self.mounts))
                else:
                    self.refused += 1
        last = self._last_map_ns
        if last is None or msg.stamp_ns - last >= self.period_ns or set_back(msg.stamp_ns, last):
            self._last_map_ns = msg.stamp_ns
            out.append(("map", self.map_msg(msg.stamp_ns)))
        return out

    def finish(self) -> Outputs:
        """The end of the run (once): the association's last word on the whole history
        (:meth:`mapping.association.SampleAssociation.finish`: its pose graph solved,
        the map rebuilt at its poses when that draws the walls sharper), and the final
        map, stamped at the last scan. Nothing before the first scan."""
        if self.finished or self._last_scan_ns is None:
            return []
        self.finished = True
        if self.da is not None:
            self.da.finish()
        return [("map", self.map_msg(self._last_scan_ns))]

    def summary(self) -> str:
        """What became of the scans: mapped, left out by the motion filter, without a
        pose to map them at, of a width that does not match the mounts; and, after
        :meth:`finish`, what the pose graph did."""
        f = self.filter
        text = (f"{self.scans + self.mismatched} IR scans: {f.kept} mapped, {f.dropped} left "
                f"out by the motion filter, {f.unplaced} without a finite pose, "
                f"{self.mismatched} of the wrong width")  # fmt: skip
        refused = self.da.refused_scans if self.da is not None else self.refused
        if refused:
            text += f", {refused} refused beyond the grid's max_cells"
        if self.finished and self.da is not None and self.da.graph_outcome:
            text += f"; pose graph: {self.da.graph_outcome}"
        return text

    def map_msg(self, stamp_ns: int) -> Any:
        return to_grid_msg(self.grid, stamp_ns, "map")
