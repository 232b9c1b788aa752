"""Pipeline adapter of the CP localizer (ekf-vs-cp.txt eq. (5)): ``feed(topic, msg)``.

For the daemon's pipeline (hilnav/pipeline.py, ``make_localization``)::

    svc = CPService(CPConfig(...), robot="r1", initial=None, publish_every_s=0.5)
    svc.feed("odometry" | "gyro" | "gps" | "relative", msg) -> [("pose_box", PoseBox)]
    svc.feed_other(robot, "pose_box", PoseBox) -> []      # peers' boxes (cooperative)
    svc.drop_peer(robot)                                   # a peer left the fleet

A box is output at most every ``publish_every_s`` of message time (always on the first
step). No clocks, no threads: the same messages give the same boxes (replay).
"""

from __future__ import annotations

from typing import Any

from localization.cp import CPConfig, CPLocalizer
from msgs import PoseBox


class CPService:
    """The CP localizer behind the pipeline's ``feed(topic, msg)`` contract."""

    TOPICS = ("odometry", "gyro", "gps", "relative")

    def __init__(
        self,
        config: CPConfig | None = None,
        robot: str = "",
        initial: PoseBox | None = None,
        publish_every_s: float = 0.5,
    ) -> None:
        self.cp = CPLocalizer(config, robot=robot, initial=initial)
        self.period_ns = int(publish_every_s * 1e9)
        self._last_out: int | None = None

    def feed(self, topic: str, msg: Any) -> list[tuple[str, Any]]:
        if topic not in self.TOPICS:
            return []
        box = self.cp.feed(msg)
        if box is None:
            return []
        if self._last_out is not None and box.stamp_ns - self._last_out < self.period_ns:
            return []
        self._last_out = box.stamp_ns
        return [("pose_box", box)]

    def feed_other(self, robot: str, topic: str, msg: Any) -> list[tuple[str, Any]]:
        if topic == "pose_box" and isinstance(msg, PoseBox) and msg.robot == robot:
            self.cp.feed_peer_box(msg)
        return []

    def drop_peer(self, robot: str) -> None:
        self.cp.drop_peer(robot)
