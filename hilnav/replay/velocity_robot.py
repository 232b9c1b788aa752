"""Replay pipeline of one robot with velocity odometry and range-bearing sensors (MRCLAM).

:class:`VelocityRobotPipeline` has the ``feed(topic, msg) -> [(topic, msg)]`` contract of
``hilnav.pipeline.Pipeline``, for the topics of ``hilnav import mrclam``:

- ``velocity`` (msgs.VelocityOdometry) -> ``dead_reckoning`` (msgs.PoseEstimate): the
  velocities integrated from the robot's initial pose (fusion.dead_reckoning), at every
  message; frame ``map`` when the log gives the initial pose (metadata
  ``initial_pose.<robot>``), else ``odom`` from the origin.
- ``landmark_map`` (msgs.LandmarkMap): kept (``self.landmark_map``).
- every message also goes to each service of ``self.localizers``, the localizers that
  take velocity odometry, the landmark map and range-bearing measurements, each with
  ``feed(topic, msg)`` and ``feed_other(robot, topic, msg)`` (the other robots' outputs,
  hilnav.replay.multi_robot). The real-robot CP (localization.mrclam_cp_service:
  ``pose_box`` every 0.1 s, ``peer_sighting``), which starts knowing nothing; with an
  initial pose, the MRCLAM EKF (localization.mrclam_service: ``pose`` every 0.05 s,
  ``peer_fix``). Range-bearing messages that no localizer takes are counted in
  ``self.unused``.

The outputs the other robots need (``SHARED_OUTPUTS``: the EKF's published estimates and
its position fixes of the robots it saw, the CP's sightings with its box; its boxes are a
peer topic of hilnav.topics) go to their ``feed_other``.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from fusion.dead_reckoning import VelocityDeadReckoning
from localization.cp_config import RangeBearingCPConfig
from localization.mrclam_config import MrclamEkfConfig
from localization.mrclam_cp_service import MrclamCpService
from localization.mrclam_service import MrclamEkfService
from msgs import LandmarkMap, Pose2D, RangeBearing, VelocityOdometry

Outputs = list[tuple[str, Any]]
RANGE_BEARING_TOPICS = ("landmark_range_bearing", "peer_range_bearing")
#: Outputs of a robot's localizers that the other robots' localizers take.
SHARED_OUTPUTS = ("pose", "peer_fix", "peer_sighting")


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
    """The services of one velocity-odometry robot (see the module docstring).
    ``ekf``: the MRCLAM EKF's configuration (None: its replay default; False: no EKF);
    ``cp``: the CP's (None: ``RangeBearingCPConfig()``; False: no CP)."""

    shared_outputs = SHARED_OUTPUTS

    def __init__(
        self,
        robot: str,
        initial: Pose2D | None = None,
        ekf: MrclamEkfConfig | None | bool = None,
        cp: RangeBearingCPConfig | None | bool = None,
    ) -> None:
        self.robot = robot
        frame = "map" if initial is not None else "odom"
        self.dr = VelocityDeadReckoning(initial, frame=frame, source=f"{robot}/dead_reckoning")
        self.landmark_map: LandmarkMap | None = None
        self.unused: Counter = Counter()
        self.services = ["dead_reckoning"]
        self.localizers: list[Any] = []
        if cp is not False:
            cfg_cp = cp if isinstance(cp, RangeBearingCPConfig) else None
            self.localizers.append(MrclamCpService(robot, cfg_cp))
            self.services.append("mrclam_cp")
        if initial is not None and ekf is not False:
            cfg = ekf if isinstance(ekf, MrclamEkfConfig) else None
            self.localizers.append(MrclamEkfService(robot, initial, cfg))
            self.services.append("mrclam_ekf")

    def feed(self, topic: str, msg: Any) -> Outputs:
        out: Outputs = []
        if topic == "velocity" and isinstance(msg, VelocityOdometry):
            est = self.dr.feed(msg)
            if est is not None:
                out.append(("dead_reckoning", est))
        elif topic == "landmark_map" and isinstance(msg, LandmarkMap):
            self.landmark_map = msg
        elif (
            topic in RANGE_BEARING_TOPICS and isinstance(msg, RangeBearing) and not self.localizers
        ):
            self.unused[topic] += 1
        for svc in self.localizers:
            out += svc.feed(topic, msg)
        return out

    def feed_other(self, robot: str, topic: str, msg: Any) -> Outputs:
        """Another robot's outputs (its estimates, position fixes, boxes, sightings)."""
        out: Outputs = []
        for svc in self.localizers:
            out += svc.feed_other(robot, topic, msg)
        return out

    def advance(self, stamp_ns: int) -> Outputs:
        """Everything up to ``stamp_ns`` is in (a clock, for the localizers that take one)."""
        out: Outputs = []
        for svc in self.localizers:
            adv = getattr(svc, "advance", None)
            if adv is not None:
                out += adv(stamp_ns)
        return out

    def drop_peer(self, robot: str) -> None:
        """A peer left (fleet): its box is no longer used."""
        for svc in self.localizers:
            drop = getattr(svc, "drop_peer", None)
            if drop is not None:
                drop(robot)
