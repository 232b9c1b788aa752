"""A log read into per-robot tracks: poses of each source, truth, GPS, boxes, maps, diagnostics.

Topics are ``/<robot>/<kind>``. Times are the messages' own stamps (``stamp_ns``: one host
clock in the daemon, the device read time, carried over to the estimates), or the MCAP log
time for a message without one — log times of service outputs are when the service loop
got to them, which lags behind when the loop stalls.

The truth's gaps (msgs.GroundTruth ``gap_before_s`` > 0: a data set's motion capture lost
the robot) are kept on the truth track; :meth:`Track.covered` says which instants lie
outside them, and only those are scored.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hilnav.log.reader import ReadStats, decode_record, iter_raw, message_types
from hilnav.topics import split_log_topic
from msgs import (
    AssociationReport,
    DeviceDiagnostics,
    GpsFix,
    GroundTruth,
    GyroSample,
    HeadingEstimate,
    IrScan,
    OccupancyGridMsg,
    PoseBox,
    PoseEstimate,
    RobotInfo,
    RobotOdometry,
    VehicleControl,
    VelocityOdometry,
)

NS = 1_000_000_000
# Sources in their own frame (dead reckoning from where they started): compared after a
# rigid alignment of their first sample to the reference.
DEAD_RECKONING = ("odometry", "gyro", "heading", "dead_reckoning")


@dataclass
class Track:
    """A time series of planar poses (log times in ns)."""

    t: list[int] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    theta: list[float] = field(default_factory=list)
    var: list[tuple[float, float, float]] = field(default_factory=list)  # sx^2, sy^2, st^2
    gaps: list[tuple[int, int]] = field(default_factory=list)  # (start, end) ns, nothing known

    def add(self, t: int, x: float, y: float, theta: float, var=None) -> None:
        self.t.append(int(t))
        self.x.append(float(x))
        self.y.append(float(y))
        self.theta.append(float(theta))
        if var is not None:
            self.var.append(var)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(self.t, dtype=np.int64)
        order = np.argsort(t, kind="stable")
        return (
            t[order],
            np.asarray(self.x)[order],
            np.asarray(self.y)[order],
            np.asarray(self.theta)[order],
        )

    def __len__(self) -> int:
        return len(self.t)

    def covered(self, t: np.ndarray) -> np.ndarray:
        """Mask of the instants ``t`` (ns) that lie in no gap (strictly inside one: not)."""
        t = np.asarray(t, dtype=np.int64)
        ok = np.ones(len(t), dtype=bool)
        for lo, hi in self.gaps:
            ok &= ~((t > lo) & (t < hi))
        return ok


@dataclass
class RobotLog:
    """Everything of one robot that the analysis uses."""

    name: str
    truth: Track = field(default_factory=Track)
    sources: dict[str, Track] = field(default_factory=dict)  # pose, heading, odometry, gyro
    gps: Track = field(default_factory=Track)
    speeds: list[tuple[int, float]] = field(default_factory=list)  # (t, m/s) of controls
    boxes: list[tuple[int, PoseBox]] = field(default_factory=list)
    last_map: OccupancyGridMsg | None = None
    maps: int = 0
    reference_map: OccupancyGridMsg | None = None  # a data set's map at its reference poses
    ir: list[IrScan] = field(default_factory=list)
    associations: list[AssociationReport] = field(default_factory=list)
    diagnostics: dict[str, list[DeviceDiagnostics]] = field(default_factory=dict)
    info: RobotInfo | None = None
    landmarks: Any = None  # the last landmark map (msgs.landmarks.LandmarkMap: xs, ys)
    landmark_maps: int = 0
    counts: Counter = field(default_factory=Counter)


def load(path: str | Path, stats: ReadStats | None = None) -> dict[str, RobotLog]:
    """Group a log's messages by robot (raw bytes are skipped, not decoded)."""
    st = stats if stats is not None else ReadStats()
    types = message_types()
    robots: dict[str, RobotLog] = {}
    for r in iter_raw(path, stats=st, as_written=True):
        robot, kind = split_log_topic(r.topic)
        if kind.startswith("raw/") or kind.startswith("fox/") or not robot:
            continue
        m = decode_record(r, st, types)
        if m is None:
            continue
        rl = robots.setdefault(robot, RobotLog(robot))
        rl.counts[kind] += 1
        msg = m.msg
        stamp = getattr(msg, "stamp_ns", None)
        t = stamp if isinstance(stamp, int) and stamp > 0 else m.log_time_ns
        if isinstance(msg, GroundTruth):
            rl.truth.add(t, msg.pose.x, msg.pose.y, msg.pose.theta)
            if msg.gap_before_s > 0:
                rl.truth.gaps.append((t - round(msg.gap_before_s * NS), t))
        elif isinstance(msg, PoseEstimate):
            c = msg.covariance
            var = (c[0], c[4], c[8]) if len(c) == 9 else None
            rl.sources.setdefault(kind, Track()).add(t, msg.pose.x, msg.pose.y, msg.pose.theta, var)
        elif isinstance(msg, HeadingEstimate):
            var = (math.nan, math.nan, msg.variance_rad2)
            rl.sources.setdefault(kind, Track()).add(t, msg.pose.x, msg.pose.y, msg.theta_rad, var)
        elif isinstance(msg, RobotOdometry):
            rl.sources.setdefault("odometry", Track()).add(
                t, msg.pose.x, msg.pose.y, msg.pose.theta
            )
        elif isinstance(msg, GyroSample):
            rl.sources.setdefault("gyro", Track()).add(t, math.nan, math.nan, msg.angle_rad)
        elif isinstance(msg, GpsFix):
            if msg.east_m is not None and msg.north_m is not None:
                rl.gps.add(t, msg.east_m, msg.north_m, math.nan)
        elif isinstance(msg, VehicleControl):
            rl.speeds.append((t, msg.speed_mps))
        elif isinstance(msg, VelocityOdometry):
            rl.speeds.append((t, msg.linear_mps))
        elif isinstance(msg, PoseBox):
            rl.boxes.append((t, msg))
        elif isinstance(msg, OccupancyGridMsg) and kind == "reference_map":
            rl.reference_map = msg
        elif isinstance(msg, OccupancyGridMsg):
            rl.last_map = msg
            rl.maps += 1
        elif isinstance(msg, IrScan):
            rl.ir.append(msg)
        elif isinstance(msg, AssociationReport):
            rl.associations.append(msg)
        elif isinstance(msg, DeviceDiagnostics):
            rl.diagnostics.setdefault(msg.device, []).append(msg)
        elif isinstance(msg, RobotInfo):
            rl.info = msg
        elif hasattr(msg, "xs") and hasattr(msg, "ys") and hasattr(msg, "ids"):
            rl.landmarks = msg
            rl.landmark_maps += 1
    return robots
