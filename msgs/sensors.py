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
    """One NMEA epoch combined into a fix, as gpsd would report it (its TPV object).

    mode: 0 unknown, 1 no fix, 2 2D, 3 3D. quality: GGA fix quality (0 invalid, 1 GPS,
    2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning). status: gpsd's fix status (0
    unknown, 1 GPS, 2 DGPS, 3 RTK fixed, 4 RTK float, 5 dead reckoning, 6 GNSS + dead
    reckoning, 7 time only, 8 simulated, 9 P(Y) code). time_utc is ISO 8601 or "".
    east_m/north_m are local metres about the datum (None before a datum is set).

    The fields after ``talker`` follow gpsd's TPV in SI units: altitude above the WGS84
    ellipsoid, climb (m/s, up), gpsd's error estimates at 95 % (``ep*``: x, y, vertical,
    horizontal, spherical in metres, time in s, speed and climb in m/s, track in degrees),
    magnetic variation and track (degrees), DGPS age (s) and station, velocity north, east
    and down (m/s), leap seconds (GPS - UTC, s) and the GST pseudorange noise statistics
    (rms of the ranges, semi-major and semi-minor axis of the error ellipse, metres, and
    its orientation, degrees from true north; std_lat/lon/alt_m are GST's sigmas).
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
    status: int = 0
    alt_hae_m: float | None = None
    climb_mps: float | None = None
    eph_m: float | None = None
    epv_m: float | None = None
    epx_m: float | None = None
    epy_m: float | None = None
    sep_m: float | None = None
    ept_s: float | None = None
    eps_mps: float | None = None
    epc_mps: float | None = None
    epd_deg: float | None = None
    magvar_deg: float | None = None
    magtrack_deg: float | None = None
    dgps_age_s: float | None = None
    dgps_station: int | None = None
    vel_n_mps: float | None = None
    vel_e_mps: float | None = None
    vel_d_mps: float | None = None
    leap_seconds: int | None = None
    gst_rms_m: float | None = None
    gst_major_m: float | None = None
    gst_minor_m: float | None = None
    gst_orient_deg: float | None = None


@dataclass(frozen=True, slots=True)
class GpsSatellite:
    """One satellite in view (NMEA GSV): PRN as gpsd numbers it (1-32 GPS, 33-64 and
    120-158 SBAS, 65-96 GLONASS, 193-202 QZSS, 301-336 Galileo, 401-437 BeiDou), gnss_id
    and sv_id as u-blox numbers them, elevation and azimuth (degrees), signal to noise
    (dB-Hz), and whether the fix uses it."""

    prn: int
    gnss_id: int = 0
    sv_id: int = 0
    elevation_deg: float | None = None
    azimuth_deg: float | None = None
    snr_dbhz: float | None = None
    used: bool = False


@dataclass(frozen=True, slots=True)
class GpsSky:
    """The receiver's sky, as gpsd's SKY object: satellites in view (NMEA GSV, the last
    complete set) and used (GSA), and the dilutions of precision. hdop/vdop/pdop come from
    the receiver (GSA, GGA); x/y/t/gdop, and any the receiver does not give, are computed
    from the geometry of the satellites used, as gpsd does. n_sat is None before a
    complete set of GSV sentences; time_utc is the epoch's (ISO 8601 or "")."""

    stamp_ns: int
    time_utc: str = ""
    satellites: tuple[GpsSatellite, ...] = ()
    n_sat: int | None = None
    u_sat: int | None = None
    hdop: float | None = None
    vdop: float | None = None
    pdop: float | None = None
    xdop: float | None = None
    ydop: float | None = None
    tdop: float | None = None
    gdop: float | None = None
    talker: str = ""
