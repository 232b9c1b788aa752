"""The services of one robot wired together: device messages in, estimates and maps out.

``Pipeline(config).feed(topic, msg)`` takes one device message (topics of INTERFACES.md:
odometry, gyro, gps, ir; others are ignored) and returns the ``(topic, msg)`` outputs it
caused, in a fixed order: heading, pose, pose_box, association, map. No threads, no
clocks (time is the messages' stamps), seeded randomness: the same inputs in the same
order give the same outputs, which is what ``hilnav replay`` relies on. Each service is
switched on or off by ``[services.*].enabled``.

Wiring (see hilnav.services for each adapter):

    odometry, gyro ------> heading ---> mapping (with each ir scan) ---> map, association
    odometry, gyro, gps -> pose (frame "map")
    odometry, gyro, gps -> localization (CP) ---> pose_box
"""

from __future__ import annotations

from typing import Any

from hilnav.config import RobotConfig
from hilnav.services import HeadingAdapter, LocalizationAdapter, MappingAdapter, PoseAdapter

INPUT_TOPICS = ("odometry", "gyro", "gps", "ir")


class Pipeline:
    """Deterministic service graph of one robot (see the module docstring)."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        sv = config.services
        self.heading = HeadingAdapter(config) if sv.heading.enabled else None
        self.pose = PoseAdapter(config) if sv.pose.enabled else None
        self.localization = LocalizationAdapter(config) if sv.localization.enabled else None
        self.mapping = MappingAdapter(config) if sv.mapping.enabled else None
        self.latest: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    @property
    def services(self) -> list[str]:
        """Names of the services that run."""
        names = ("heading", "pose", "localization", "mapping")
        return [n for n in names if getattr(self, n) is not None]

    def feed(self, topic: str, msg: Any) -> list[tuple[str, Any]]:
        """Outputs caused by one input message (none for topics the services ignore)."""
        if topic not in INPUT_TOPICS:
            return []
        self.counts[topic] = self.counts.get(topic, 0) + 1
        out: list[tuple[str, Any]] = []
        if self.heading is not None:
            out += self.heading.feed(topic, msg)
        if self.pose is not None:
            out += self.pose.feed(topic, msg)
        if self.localization is not None:
            out += self.localization.feed(topic, msg)
        if self.mapping is not None:
            for t, m in [*out, (topic, msg)]:
                if t in ("heading", "ir"):
                    out += self.mapping.feed(t, m)
        for t, m in out:
            self.latest[t] = m
        return out

    def feed_other(self, robot: str, topic: str, msg: Any) -> list[tuple[str, Any]]:
        """Messages of other fleet robots (cooperative localization: their pose boxes)."""
        if self.localization is not None and hasattr(self.localization, "feed_other"):
            return list(self.localization.feed_other(robot, topic, msg))
        return []

    def map_now(self, stamp_ns: int) -> Any | None:
        """The current map as a message (for the map queryable), or None if no mapping."""
        return self.mapping.map_msg(stamp_ns) if self.mapping is not None else None
