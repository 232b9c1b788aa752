"""Which IR scans go into the grid: a motion filter before the update of
ir-grid-mapping eq. 5-6 (beyond the paper, which inserts every scan).

The log-odds update of eq. 6 adds each scan's evidence as if it were independent of the
last. Scans taken from (almost) the same pose are not: the same wall seen again from a
centimetre further on, with the same sensor error, the same pose error. At the daemon's
20 Hz and a walking pace the robot moves 1.5 cm between scans, a third of a 5 cm cell,
so every cell near a wall is counted several times over from one view, and standing still
counts it twenty times a second. Mapping systems filter the scans by motion for this
reason (and for the time): Cartographer's motion filter, GMapping's linear and angular
update distances. Here a scan is inserted when, since the last one inserted,

- the robot has moved ``min_travel_m`` (default: one cell of the daemon's grid), or
- turned ``min_turn_rad`` (default 2 deg: 9 cm across at the Sharp's 5.5 m range), or
- ``max_interval_s`` has passed (default 1 s: a robot standing still still sees what
  moves in front of it, once a second instead of twenty times), or
- it is the first.

``enabled`` False maps every scan (the paper); a threshold of ``inf`` switches that
trigger off. A scan whose pose is not finite is not placed anywhere: :meth:`keep` says
no and counts it in ``unplaced`` (``kept + dropped + unplaced`` = the scans seen).

Pure: poses and stamps in, a decision out (no clock).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from msgs import Pose2D
from numerics.angles import wrap


@dataclass(frozen=True)
class MotionFilterConfig:
    """Thresholds of :class:`MotionFilter` (each > 0; ``inf``: that trigger off);
    ``enabled`` False inserts every scan (the paper)."""

    min_travel_m: float = 0.05
    min_turn_rad: float = math.radians(2.0)
    max_interval_s: float = 1.0
    enabled: bool = True

    def __post_init__(self) -> None:
        for name in ("min_travel_m", "min_turn_rad", "max_interval_s"):
            v = getattr(self, name)
            if not v > 0:  # NaN too
                raise ValueError(f"motion filter {name} must be > 0 (inf: off), got {v}")


class MotionFilter:
    """Decides scan by scan whether the grid takes it (module doc)."""

    def __init__(self, config: MotionFilterConfig | None = None) -> None:
        self.config = config or MotionFilterConfig()
        self._last: tuple[float, float, float, int] | None = None
        self.kept = 0
        self.dropped = 0
        self.unplaced = 0

    def keep(self, pose: Pose2D, stamp_ns: int) -> bool:
        """True if the scan taken at ``pose``, ``stamp_ns`` goes into the grid."""
        cfg = self.config
        last = self._last
        if not (math.isfinite(pose.x) and math.isfinite(pose.y) and math.isfinite(pose.theta)):
            self.unplaced += 1  # nowhere to put it, nor to measure the next one from
            return False
        take = (
            not cfg.enabled
            or last is None
            or math.hypot(pose.x - last[0], pose.y - last[1]) >= cfg.min_travel_m
            or abs(wrap(pose.theta - last[2])) >= cfg.min_turn_rad
            or (stamp_ns - last[3]) >= cfg.max_interval_s * 1e9
            or stamp_ns < last[3]  # the clock went back (a replayed or reset source)
        )
        if take:
            self._last = (pose.x, pose.y, pose.theta, stamp_ns)
            self.kept += 1
        else:
            self.dropped += 1
        return take
