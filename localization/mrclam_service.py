"""The MRCLAM EKF as the service of one robot, message by message (``hilnav replay`` of an
``hilnav import mrclam`` log, hilnav/replay/velocity_robot.py): the same steps as the
batch runner (localization/mrclam_filter.py's :class:`JointEkf` over this one robot), so
the replay gives the batch's ``cooperation = "split_ci"`` track.

``feed(topic, msg) -> [(topic, msg)]``:

- ``landmark_map`` (msgs.LandmarkMap): the known landmarks (ids, positions, covariance);
- ``velocity`` (msgs.VelocityOdometry): the commanded (v, w), applied ``command_lag_s``
  after their stamp; the first one starts the filter at the robot's initial pose;
- ``landmark_range_bearing``, ``peer_range_bearing`` (msgs.RangeBearing): the camera's
  measurements; a peer measurement is fused with the peer's latest published estimate
  by split covariance intersection, and gives a ``peer_fix`` (msgs.PeerFix) for the
  peer's own filter (``peer_update = "both"``).

Outputs: ``pose`` (msgs.PoseEstimate, frame "map", the pose and its 3x3 covariance) every
``output_period_s`` from the start (the filter predicted to that instant), and
``peer_fix``. ``feed_other(robot, topic, msg)`` takes the other robots' ``pose`` (their
published estimates) and the ``peer_fix`` meant for this robot. Measurements before the
first velocity message, of landmarks not in the map, and robot measurements in
``cooperation = "none"`` are counted (``counts``) and skipped.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import replace
from typing import Any

import numpy as np

from localization.mrclam_config import MrclamEkfConfig
from localization.mrclam_filter import Estimate, JointEkf, PositionFix
from msgs import (
    LandmarkMap,
    PeerFix,
    Pose2D,
    PoseEstimate,
    RangeBearing,
    VelocityOdometry,
    wrap_angle,
)

NS = 1e-9


def _cov2(c: tuple[float, float, float]) -> np.ndarray:
    return np.array([[c[0], c[1]], [c[1], c[2]]])


class MrclamEkfService:
    """One robot's MRCLAM EKF (module docstring). ``config`` defaults to the batch's
    defaults with ``cooperation = "split_ci"``; "joint" needs every robot's state in one
    filter and is refused."""

    def __init__(self, robot: str, initial: Pose2D, config: MrclamEkfConfig | None = None):
        cfg = config or replace(MrclamEkfConfig(), cooperation="split_ci")
        if cfg.cooperation == "joint":
            raise ValueError(
                "one robot's service cannot run the joint filter: use split_ci, ci or none"
            )
        self.robot, self.cfg = robot, cfg
        self.initial = np.array([initial.x, initial.y, initial.theta])
        self.f: JointEkf | None = None
        self.landmarks: dict[int, tuple[float, float, float, float]] = {}
        self.peers: dict[str, Estimate] = {}
        self.counts: Counter = Counter()  # before the filter starts

    @property
    def all_counts(self) -> Counter:
        """The filter's counts and those from before it started."""
        out = Counter(self.counts)
        if self.f is not None:
            out.update(self.f.r[self.robot].counts)
        return out

    def feed(self, topic: str, msg: Any) -> list[tuple[str, Any]]:
        if topic == "landmark_map" and isinstance(msg, LandmarkMap):
            self.landmarks = {
                int(i): (x, y, max(vx, 0.0) ** 0.5, max(vy, 0.0) ** 0.5)
                for i, x, y, vx, vy in zip(
                    msg.ids, msg.xs, msg.ys, msg.cov_xx, msg.cov_yy, strict=True
                )
            }
            if self.f is not None:
                self.f.marks = dict(self.landmarks)
            return []
        if topic == "velocity" and isinstance(msg, VelocityOdometry):
            t = msg.stamp_ns * NS
            if self.f is None:
                self.f = JointEkf(self.cfg, self.landmarks)
                cov = np.diag(np.square(np.asarray(self.cfg.init_sigma, float)))
                self.f.add_robot(self.robot, t, self.initial, cov)
            self.f.command(self.robot, t, msg.linear_mps, msg.angular_radps)
            self.f.process_to(self.robot, t)
            return self._drain()
        if isinstance(msg, RangeBearing) and topic in (
            "landmark_range_bearing",
            "peer_range_bearing",
        ):
            return self._measurement(msg)
        return []

    def _measurement(self, msg: RangeBearing) -> list[tuple[str, Any]]:
        me, f, t = self.robot, self.f, msg.stamp_ns * NS
        if f is None or t < f.r[me].t0:
            self.counts["before_start"] += 1
            return []
        counts = f.r[me].counts
        if not msg.range_m > 0.0:
            f.process_to(me, t)
            counts["invalid"] += 1
            return self._drain()
        z = np.array([msg.range_m, msg.bearing_rad])
        fix = None
        if msg.landmark:
            if msg.subject in f.marks:
                f.landmark(me, t, msg.subject, z)
            else:
                f.process_to(me, t)
                counts["unknown_subject"] += 1
        elif self.cfg.cooperation == "none" or msg.target == me:
            f.process_to(me, t)
            counts["robot_ignored"] += 1
        else:
            both = self.cfg.peer_update == "both"
            fix = f.robot_split(me, t, msg.target, z, self.peers.get(msg.target), both)
        out = self._drain()
        if fix is not None:
            out.append(("peer_fix", self._fix_msg(fix)))
        return out

    def _fix_msg(self, fix: PositionFix) -> PeerFix:
        cd, ci = fix.c_dep, fix.c_ind
        return PeerFix(
            round(fix.t / NS),
            str(fix.robot),
            str(fix.observer),
            float(fix.p[0]),
            float(fix.p[1]),
            (float(cd[0, 0]), float(cd[0, 1]), float(cd[1, 1])),
            (float(ci[0, 0]), float(ci[0, 1]), float(ci[1, 1])),
        )

    def feed_other(self, robot: str, topic: str, msg: Any) -> list[tuple[str, Any]]:
        """Another robot's published estimate, or its position fix of this robot."""
        if topic == "pose" and isinstance(msg, PoseEstimate) and robot != self.robot:
            cov = np.array(msg.covariance, float).reshape(3, 3)
            mean = np.array([msg.pose.x, msg.pose.y, msg.pose.theta])
            self.peers[robot] = (msg.stamp_ns * NS, mean, cov)
        elif topic == "peer_fix" and isinstance(msg, PeerFix) and msg.robot == self.robot:
            if self.f is None or msg.stamp_ns * NS < self.f.r[self.robot].t0:
                self.counts["seen_before_start"] += 1
                return []
            p = np.array([msg.x_m, msg.y_m])
            fix = PositionFix(
                msg.stamp_ns * NS,
                self.robot,
                msg.observer,
                p,
                _cov2(msg.cov_estimate),
                _cov2(msg.cov_measurement),
            )
            self.f.fix_update(self.robot, fix)
            return self._drain()
        return []

    def _drain(self) -> list[tuple[str, Any]]:
        """The new grid rows as ``pose`` messages."""
        assert self.f is not None
        rows = self.f.r[self.robot].rows
        out = []
        for t, mean, cov, grid in rows:
            if grid:
                pose = Pose2D(float(mean[0]), float(mean[1]), wrap_angle(float(mean[2])))
                flat = tuple(float(v) for v in cov.ravel())
                out.append(
                    (
                        "pose",
                        PoseEstimate(round(t / NS), pose, flat, "map", f"{self.robot}/mrclam_ekf"),
                    )
                )
        del rows[:]  # drained: the service keeps no track
        return out
