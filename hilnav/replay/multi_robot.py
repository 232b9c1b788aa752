"""Replay of several robots of one log at once: one pipeline per robot, boxes shared.

A data set of several robots (``hilnav import mrclam``) is replayed as a fleet in one
process: :class:`MultiRobotPipeline` holds one single-robot pipeline per robot (anything
with ``feed(topic, msg) -> [(topic, msg)]``), feeds each its own inputs, and hands every
output on a peer topic (:data:`hilnav.topics.PEER_TOPICS`: the pose boxes) to the other
robots' ``feed_other(robot, topic, msg)``, as the daemons of a fleet receive them over
Zenoh. ``feed_robot(robot, topic, msg)`` returns ``(robot, topic, msg)`` triples: whose
output it is. Deterministic: robots in a fixed order, no clock.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hilnav.topics import PEER_TOPICS

Triples = list[tuple[str, str, Any]]


class MultiRobotPipeline:
    """One pipeline per robot of ``robots``, made by ``factory(robot)``."""

    def __init__(self, robots: list[str], factory: Callable[[str], Any]) -> None:
        if not robots:
            raise ValueError("a multi-robot replay needs at least one robot")
        self.robots = tuple(robots)
        self.pipes = {r: factory(r) for r in self.robots}
        first = self.pipes[self.robots[0]]
        self.services = list(getattr(first, "services", []))

    def feed_robot(self, robot: str, topic: str, msg: Any) -> Triples:
        """The outputs ``robot``'s message caused, its own and its peers' (in that order)."""
        out: Triples = [(robot, t, m) for t, m in self.pipes[robot].feed(topic, msg)]
        for t, m in [(t, m) for _, t, m in out if t in PEER_TOPICS]:
            for other in self.robots:
                feed_other = getattr(self.pipes[other], "feed_other", None)
                if other != robot and feed_other is not None:
                    out += [(other, t2, m2) for t2, m2 in feed_other(robot, t, m)]
        return out
