"""Replay pipeline of one robot with velocity odometry and range-bearing sensors (MRCLAM).

:class:`VelocityRobotPipeline` has the ``feed(topic, msg) -> [(topic, msg)]`` contract of
``hilnav.pipeline.Pipeline``, for the topics of ``hilnav import mrclam``:

- ``velocity`` (msgs.VelocityOdometry) -> ``dead_reckoning`` (msgs.PoseEstimate): the
  velocities integrated from the robot's initial pose (fusion.dead_reckoning), at every
  message; frame ``map`` when the log gives the initial pose (metadata
  ``initial_pose.<robot>``), else ``odom`` from the origin.
- ``landmark_map`` (msgs.LandmarkMap): kept (``self.landmark_map``).
- ``landmark_range_bearing``, ``peer_range_bearing`` (msgs.RangeBearing): counted in
  ``self.unused``. They are service inputs (hilnav.topics.SERVICE_INPUTS), so replay feeds
  them here in log order: the hook where the guaranteed (CP) and EKF localizers that take
  landmark and robot-to-robot range-bearing plug in, with the peers' boxes arriving
  through ``feed_other`` (hilnav.replay.multi_robot).

The EKF of localization.ekf is not run: its message API takes wheel odometry, gyro and
GPS, none of which such a robot has, and velocity odometry with range-bearing updates is
what it gains with those localizers.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from fusion.dead_reckoning import VelocityDeadReckoning
from msgs import LandmarkMap, Pose2D, RangeBearing, VelocityOdometry

Outputs = list[tuple[str, Any]]
RANGE_BEARING_TOPICS = ("landmark_range_bearing", "peer_range_bearing")


def initial_poses(meta: dict[str, str]) -> dict[str, Pose2D]:
    """``initial_pose.<robot>`` = "x,y,theta" of the log's metadata, per robot (malformed
    entries are left out: that robot starts at the origin of its odom frame)."""
    out = {}
    for key, value in meta.items():
        if not key.startswith("initial_pose."):
            continue
        try:
            x, y, th = (float(v) for v in value.split(","))
        except ValueError:
            continue
        out[key.split(".", 1)[1]] = Pose2D(x, y, th)
    return out


class VelocityRobotPipeline:
    """The services of one velocity-odometry robot (see the module docstring)."""

    def __init__(self, robot: str, initial: Pose2D | None = None) -> None:
        self.robot = robot
        frame = "map" if initial is not None else "odom"
        self.dr = VelocityDeadReckoning(initial, frame=frame, source=f"{robot}/dead_reckoning")
        self.landmark_map: LandmarkMap | None = None
        self.unused: Counter = Counter()
        self.services = ["dead_reckoning"]

    def feed(self, topic: str, msg: Any) -> Outputs:
        if topic == "velocity" and isinstance(msg, VelocityOdometry):
            est = self.dr.feed(msg)
            return [] if est is None else [("dead_reckoning", est)]
        if topic == "landmark_map" and isinstance(msg, LandmarkMap):
            self.landmark_map = msg
        elif topic in RANGE_BEARING_TOPICS and isinstance(msg, RangeBearing):
            self.unused[topic] += 1  # the localizers' hook (module docstring)
        return []

    def feed_other(self, robot: str, topic: str, msg: Any) -> Outputs:
        """Another robot's outputs (its pose boxes, for cooperative localization)."""
        return []
