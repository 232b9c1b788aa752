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

    Bounds may be infinite (an unknown heading); the heading interval may be unwrapped
    (any 2 pi k shift of it holds). ``status`` is what the localizer says of its
    guarantee ("" when it says nothing; the real-robot CP: ok, cold, relaxed, reinit,
    lost, unknown) and ``alert_stamp_ns`` when it last had to weaken it (relaxed,
    reinit, lost; 0: never), so that peers can hold its boxes back for a while.
    Decoding refuses NaN."""

    FLOATS: ClassVar[str] = "no_nan"

    stamp_ns: int
    robot: str
    x: Interval
    y: Interval
    theta: Interval
    frame: str = "map"
    status: str = ""
    alert_stamp_ns: int = 0

    @property
    def area_m2(self) -> float:
        return self.x.width * self.y.width


@dataclass(frozen=True, slots=True)
class PeerFix:
    """Robot ``observer`` saw robot ``robot`` at (x_m, y_m) in ``frame`` at ``stamp_ns``:
    the observer's pose estimate combined with its range-bearing measurement of it, for
    the robot's own filter (split covariance intersection). The 2x2 covariances (xx, xy,
    yy, m^2) of the part that comes from the observer's estimate (``cov_estimate``: of
    unknown correlation with the robot's own estimate) and of the part that comes from
    the measurement noise (``cov_measurement``: independent of every estimate).
    Decoding refuses non-finite numbers."""

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    robot: str
    observer: str
    x_m: float
    y_m: float
    cov_estimate: tuple[float, float, float]
    cov_measurement: tuple[float, float, float]
    frame: str = "map"


@dataclass(frozen=True, slots=True)
class PeerSighting:
    """Robot ``observer`` measured robot ``robot`` at ``range_m``, ``bearing_rad`` (in the
    observer's body frame) at ``stamp_ns``, when its own guaranteed box was ``box`` (and
    its ``pieces``): for the seen robot's CP, an observation of itself (cooperative CP on
    real robots). Decoding refuses NaN."""

    FLOATS: ClassVar[str] = "no_nan"

    stamp_ns: int
    robot: str
    observer: str
    range_m: float
    bearing_rad: float
    box: PoseBox
    #: the observer's pieces whose hull is ``box`` (heading slices, each with its own
    #: position box; the observer is in one of them), 6 numbers each: x lo, x hi, y lo,
    #: y hi, theta lo, theta hi (empty: the box alone)
    pieces: tuple[float, ...] = ()
