"""Replay pipeline for landmark data sets (Victoria Park): EKF-SLAM fed controls and scans.

``hilnav.pipeline.Pipeline`` runs the Pioneer's services (odometry, gyro, GPS, IR). A log
of a landmark data set (``hilnav import victoria-park``) carries car controls and
landmark scans instead; :class:`LandmarkSlamPipeline` gives them to the
``mapping.slam.service.LandmarkSlam`` (slam-ekf.txt §4: Ackermann prediction, range-bearing
update, state augmentation) with the same ``feed(topic, msg) -> [(topic, msg)]`` contract:

- ``control`` (VehicleControl) -> ``pose`` (PoseEstimate, dead-reckoning prediction);
- ``landmark_scan`` (LandmarkScan) -> ``pose`` (after the update) and, at most every
  ``map_every_s`` of stamp time, ``landmarks`` (LandmarkMap).

Deterministic and clock-free like the daemon's pipeline.
"""

from __future__ import annotations

from typing import Any

INPUTS = ("control", "landmark_scan")


class LandmarkSlamPipeline:
    """EKF-SLAM over a landmark data set's controls and scans (see the module docstring)."""

    def __init__(self, config: Any = None, map_every_s: float = 1.0) -> None:
        from mapping.slam.service import LandmarkSlam, SlamConfig

        slam_cfg = config if isinstance(config, SlamConfig) else SlamConfig()
        self.slam = LandmarkSlam(slam_cfg)
        self.map_every_ns = int(map_every_s * 1e9)
        self._last_map_ns: int | None = None
        self.services = ["landmark_slam"]

    def feed(self, topic: str, msg: Any) -> list[tuple[str, Any]]:
        if topic == "control":
            return [("pose", self.slam.on_control(msg))]
        if topic == "landmark_scan":
            pose, lmap = self.slam.on_scan(msg)
            out: list[tuple[str, Any]] = [("pose", pose)]
            t = msg.stamp_ns
            if self._last_map_ns is None or t - self._last_map_ns >= self.map_every_ns:
                self._last_map_ns = t
                out.append(("landmarks", lmap))
            return out
        return []
