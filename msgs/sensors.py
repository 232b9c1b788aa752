"""Messages of the exteroceptive and inertial sensors: IR ranges, gyro, GPS."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

# Status of one IR range reading.
IrStatus = Literal["ok", "too_near", "too_far", "no_return", "invalid"]


@dataclass(frozen=True, slots=True)
class IrScan:
    """One sample of every Sharp IR channel of one ADC board.

    ranges_m[i] is valid only where status[i] == "ok"; voltages_v keeps the measured
    voltage; seq is the board's frame counter (to count lost frames).
    """

    stamp_ns: int
    board_id: int
    seq: int
    ranges_m: tuple[float, ...]
    status: tuple[IrStatus, ...]
    voltages_v: tuple[float, ...]
    raw_counts: tuple[int, ...] = ()


@dataclass(frozen=True, slots=True)
class GyroSample:
    """One CruzCore packet: yaw rate (rad/s) and integrated yaw angle (rad, unwrapped)."""

    stamp_ns: int
    rate_radps: float
    angle_rad: float
    angle_wrapped_rad: float = 0.0


@dataclass(frozen=True, slots=True)
class GpsFix:
    """One NMEA epoch combined into a fix, as gpsd would report it (TPV).

    mode: 0 unknown, 1 no fix, 2 2D, 3 3D. quality: GGA fix quality (0 invalid, 1 GPS,
    2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning). time_utc is ISO 8601 or "".
    east_m/north_m are local metres about the datum (None before a datum is set).
    """

    stamp_ns: int
    time_utc: str = ""
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_msl_m: float | None = None
    geoid_sep_m: float | None = None
    mode: int = 0
    quality: int = 0
    satellites: int | None = None
    hdop: float | None = None
    pdop: float | None = None
    vdop: float | None = None
    speed_mps: float | None = None
    course_deg: float | None = None
    std_lat_m: float | None = None
    std_lon_m: float | None = None
    std_alt_m: float | None = None
    east_m: float | None = None
    north_m: float | None = None
    talker: str = ""
