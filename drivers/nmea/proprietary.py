"""Proprietary NMEA sentences gpsd reads: Garmin PGRME, PGRMF, PGRMZ and Skytraq PSTI.

Same contract as :mod:`drivers.nmea.handlers`:

- PGRME: Garmin's estimated errors (taken as 50 % CEP, scaled to gpsd's 95 %);
- PGRMF: Garmin's fix data: leap seconds, time, position, fix mode, speed (km/h),
  course, PDOP and TDOP;
- PGRMZ: altitude in feet (taken as above mean sea level) and the fix mode;
- PSTI,030: Skytraq's position, altitude (MSL), velocity east/north/up and FAA mode;
  PSTI,032/035/036 only give the time (for the cycle detector).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivers.nmea.fields import atoi, ddmmyy, faa_status, fnum, latlon
from drivers.nmea.fixstate import (
    ALTITUDE_SET,
    DOP_SET,
    LATLON_SET,
    MODE_2D,
    MODE_3D,
    MODE_NO_FIX,
    MODE_SET,
    SPEED_SET,
    STATUS_SET,
    STATUS_UNK,
    TIME_SET,
    TRACK_SET,
    VNED_SET,
)

if TYPE_CHECKING:
    from drivers.nmea.session import Session

FEET_TO_METERS = 0.3048
CEP50_SIGMA, CEP95_SIGMA = 1.18, 2.45
_CEP = CEP95_SIGMA / CEP50_SIGMA
_MODE_DIGIT = {"1": MODE_NO_FIX, "2": MODE_2D, "3": MODE_3D}


def pgrme(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    if f[1][:1] == "M" and f[3][:1] == "M" and f[5][:1] == "M":
        h, v, s = fnum(f[0]), fnum(f[2]), fnum(f[4])
        if h is not None:
            new["epx"] = new["epy"] = h * (1 / 2**0.5) * _CEP
        if v is not None:
            new["epv"] = v * _CEP
        if s is not None:
            new["sep"] = s * _CEP
    return 0


def pgrmf(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    mask = 0
    if f[4][:1].isdigit():
        st.leap_seconds = atoi(f[4])
    if f[0][:1].isdigit() and f[1][:1].isdigit() and (st.leap_seconds or 0) > 0:
        mask |= TIME_SET  # the time is the NMEA date and time of day, as gpsd ends up with
    elif st.merge_hhmmss(f[3]) and (date := ddmmyy(f[2])) is not None:
        st.set_date(date)
        mask |= TIME_SET
    if f[9][:1] != "A":
        return mask
    pos = latlon(f[5], f[6], f[7], f[8])
    if pos is not None:
        new["lat"], new["lon"] = pos
        mask |= LATLON_SET
    mode = {"0": MODE_NO_FIX, "1": MODE_2D, "2": MODE_3D}.get(f[10][:1])
    if mode is not None:
        new["mode"] = mode
        mask |= MODE_SET
    kmh = fnum(f[11])
    new["speed"] = None if kmh is None else kmh / 3.6
    new["track"] = fnum(f[12])
    mask |= SPEED_SET | TRACK_SET
    for i, name in ((13, "pdop"), (14, "tdop")):
        v = fnum(f[i]) if f[i] else None
        if v is not None:
            new.setdefault("dop", {})[name] = v
            mask |= DOP_SET
    return mask


def pgrmz(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    mask = 0
    if f[1][:1] == "f" and f[0]:
        new["alt_msl"] = atoi(f[0]) * FEET_TO_METERS
        mask |= ALTITUDE_SET
    mode = _MODE_DIGIT.get(f[2][:1])
    if mode is not None:
        new["mode"] = mode
        mask |= MODE_SET
    return mask


def _dated(st: Session, tod: str, date: str) -> int:
    """A time and a ddmmyy date: merged and registered, TIME_SET; else nothing."""
    if tod and date and st.merge_hhmmss(tod):
        d = ddmmyy(date)
        if d is not None:
            st.set_date(d)
            st.register_time(tod)
            return TIME_SET
    return 0


def psti(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    kind = atoi(f[0])
    if kind == 30:
        return _psti030(st, f, new, n)
    if kind == 32 and n == 15 and f[3] == "A":
        return _dated(st, f[1], f[2])
    if (kind == 35 and n == 15) or (kind == 36 and n == 7):
        return _dated(st, f[1], f[2])
    return 0


def _psti030(st: Session, f: tuple[str, ...], new: dict, n: int) -> int:
    if n != 15:
        return 0
    if f[2][:1] == "V" or f[12][:1] == "N":
        new["status"] = STATUS_UNK
        new["mode"] = MODE_NO_FIX
        return MODE_SET | STATUS_SET
    if f[2][:1] != "A":
        return 0
    mask = _dated(st, f[1], f[11])
    pos = latlon(f[3], f[4], f[5], f[6])
    if pos is not None:
        new["lat"], new["lon"] = pos
        new["mode"] = MODE_2D
        mask |= LATLON_SET | MODE_SET
        if f[7]:
            alt = fnum(f[7])
            if alt is not None:
                new["alt_msl"] = alt
            mask |= ALTITUDE_SET
            new["mode"] = MODE_3D
    east, north, up = fnum(f[8]), fnum(f[9]), fnum(f[10])
    new["vel_n"], new["vel_e"] = north, east
    new["vel_d"] = None if up is None else -up
    new["status"] = faa_status(f[12])
    return mask | VNED_SET | STATUS_SET
