"""Outputs of the services: pose estimates with uncertainty, guaranteed pose boxes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from msgs.geometry import Interval, Pose2D


@dataclass(frozen=True, slots=True)
class PoseEstimate:
    """A pose with its 3x3 covariance (row-major, over x, y, theta) in ``frame``."""

    stamp_ns: int
    pose: Pose2D
    covariance: tuple[float, ...]
    frame: str = "map"
    source: str = ""


@dataclass(frozen=True, slots=True)
class HeadingEstimate:
    """Fused heading (rad) with its variance (rad^2), and the position it implies."""

    stamp_ns: int
    theta_rad: float
    variance_rad2: float
    pose: Pose2D


@dataclass(frozen=True, slots=True)
class PoseBox:
    """A guaranteed box on (x, y, theta) from constraint propagation.

    Bounds may be infinite (an unknown heading); decoding refuses NaN."""

    FLOATS: ClassVar[str] = "no_nan"

    stamp_ns: int
    robot: str
    x: Interval
    y: Interval
    theta: Interval
    frame: str = "map"

    @property
    def area_m2(self) -> float:
        return self.x.width * self.y.width
