"""Replay of several robots of one log at once: one pipeline per robot, outputs shared.

A data set of several robots (``hilnav import mrclam``) is replayed as a fleet in one
process: :class:`MultiRobotPipeline` holds one single-robot pipeline per robot (anything
with ``feed(topic, msg) -> [(topic, msg)]``), feeds each its own inputs, and hands every
output on a shared topic to the other robots' ``feed_other(robot, topic, msg)``, as the
daemons of a fleet receive them over Zenoh. Shared: the peer topics
(:data:`hilnav.topics.PEER_TOPICS`: the pose boxes) and the topics a pipeline lists in
its ``shared_outputs`` (the EKF's estimates and position fixes); what ``feed_other``
returns is shared the same way, in order, each output with every robot but its own.
``feed_robot(robot, topic, msg)`` returns ``(robot, topic, msg)`` triples: whose output
it is. Deterministic: robots in a fixed order, no clock.
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
        self.shared = {
            r: frozenset(PEER_TOPICS) | frozenset(getattr(p, "shared_outputs", ()))
            for r, p in self.pipes.items()
        }

    def feed_robot(self, robot: str, topic: str, msg: Any) -> Triples:
        """The outputs ``robot``'s message caused, its own and then its peers'."""
        out: Triples = [(robot, t, m) for t, m in self.pipes[robot].feed(topic, msg)]
        i = 0
        while i < len(out):
            src, t, m = out[i]
            i += 1
            if t not in self.shared[src]:
                continue
            for other in self.robots:
                feed_other = getattr(self.pipes[other], "feed_other", None)
                if other != src and feed_other is not None:
                    out += [(other, t2, m2) for t2, m2 in feed_other(src, t, m)]
        return out
