"""Range-bearing measurements: robot to robot with error bounds for cooperative
localization (ekf-vs-cp.txt §2.4), and as a data set records them, to known landmarks or
to other robots, without bounds (the localizer's configuration gives those)."""

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
class RangeBearing:
    """Robot ``robot`` measured ``target`` at ``range_m`` (metres) and ``bearing_rad`` (in
    the observer's body frame, counter-clockwise from its heading), as the sensor gave
    them: no bound is claimed.

    ``landmark`` tells what the target is: a landmark of the known map (``subject`` is its
    id in msgs.LandmarkMap.ids, ``target`` its name, e.g. "l11") or another robot
    (``target`` is that robot's name, e.g. "r2"). ``subject`` is the data set's own
    number of the target (MRCLAM: 1-5 robots, 6-20 landmarks; 0 when it has none).
    Decoding refuses non-finite numbers."""

    FLOATS: ClassVar[str] = "finite"

    stamp_ns: int
    robot: str
    target: str
    landmark: bool
    range_m: float
    bearing_rad: float
    subject: int = 0


@dataclass(frozen=True, slots=True)
class RelativeScan:
    """One scan of robot ``robot``'s range-bearing sensor: every robot it saw, with one
    stamp (each measurement's own stamp is the scan's). Cooperative localization contracts
    the robot's box with all of them at once."""

    stamp_ns: int
    robot: str
    seen: tuple[RelativeMeasurement, ...] = ()
