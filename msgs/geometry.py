"""Planar geometry values: poses, covariances, boxes. Metres and radians.

Angles are wrapped to (-pi, pi] by numerics.angles.wrap_angle (re-exported as
``msgs.wrap_angle``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Pose2D:
    """A planar pose: x, y in metres, theta in radians (wrapped to (-pi, pi])."""

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0


@dataclass(frozen=True, slots=True)
class Interval:
    """A closed interval [lo, hi]; lo > hi means empty."""

    lo: float
    hi: float

    @property
    def empty(self) -> bool:
        return self.lo > self.hi

    @property
    def width(self) -> float:
        return max(0.0, self.hi - self.lo)

    def contains(self, v: float) -> bool:
        return self.lo <= v <= self.hi
