"""Robot-to-robot measurements for cooperative localization (ekf-vs-cp.txt §2.4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar


@dataclass(frozen=True, slots=True)
class RelativeMeasurement:
    """Robot ``robot`` sees robot ``target`` at ``range_m`` and ``bearing_rad`` (in the
    observer's body frame, counter-clockwise from its heading), with guaranteed error
    bounds (the true values lie within +/- the bounds)."""

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    robot: str
    target: str
    range_m: float
    bearing_rad: float
    range_bound_m: float
    bearing_bound_rad: float


@dataclass(frozen=True, slots=True)
class RelativeScan:
    """One scan of robot ``robot``'s range-bearing sensor: every robot it saw, with one
    stamp (each measurement's own stamp is the scan's). Cooperative localization contracts
    the robot's box with all of them at once."""

    stamp_ns: int
    robot: str
    seen: tuple[RelativeMeasurement, ...] = ()
