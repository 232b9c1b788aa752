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
    """The simulated world's true pose of one robot (only the fakes know it)."""

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    robot: str
    pose: Pose2D
    linear_mps: float = 0.0
    angular_radps: float = 0.0
