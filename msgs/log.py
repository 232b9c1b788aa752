"""Messages that exist for logging and evaluation: raw device bytes and ground truth."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from msgs.geometry import Pose2D


@dataclass(frozen=True, slots=True)
class RawBytes:
    """Bytes exactly as read from (or written to) one device link, for re-parsing later.

    direction is "rx" (device to host) or "tx" (host to device).
    """

    stamp_ns: int
    device: str
    data: bytes
    direction: str = "rx"


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """The true pose of one robot: the simulated world's (only the fakes know it), or a
    data set's reference (motion capture).

    ``gap_before_s`` > 0 says that the reference lost the robot for that long before this
    sample (a gap longer than the data set's interpolable span): nothing is known between
    the previous sample and this one, and no instant in between may be scored. 0 means
    the samples are contiguous (always, for the simulated world)."""

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    robot: str
    pose: Pose2D
    linear_mps: float = 0.0
    angular_radps: float = 0.0
    gap_before_s: float = 0.0
