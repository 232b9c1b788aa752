"""One function per NMEA sentence type, reading its fields as gpsd's NMEA driver does.

Each handler ``h(session, talker, fields, new) -> mask`` puts what the sentence says into
``new`` (gpsd's ``newdata``) or into the session (date, time of day, DOPs, GST) and
returns the mask of what it set (:mod:`drivers.nmea.fixstate`). ``fields`` are the fields
after the address (gpsd's ``field[1]`` is ``fields[0]``). The rules are gpsd's:

- GGA: quality 0 keeps no status; a position is 2D, 3D with an altitude and 4 or more
  satellites, no fix with fewer than 3 satellites; a GGA whose time does not advance
  (same talker) means no fix;
- RMC: V is no fix; A/D keeps the previous fix's 3D (or makes it 3D with more than 3
  satellites used or an altitude in the current fix), else 2D; magnetic variation;
- GLL and GNS: positions (GNS with altitude, satellites, HDOP, DGPS age and station);
- VTG: track and speed unless its mode is E or N; ZDA: the date (years 1900-2200);
- GST: pseudorange noise statistics; GBS: error estimates of the same second.

``fields`` are padded with empty strings to the length the handler reads; ``n`` is the
number the sentence had (some rules depend on it, as gpsd's on its field count). GSA and
GSV are in :mod:`drivers.nmea.sky`, the proprietary sentences in
:mod:`drivers.nmea.proprietary`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivers.nmea.fields import atoi, ddmmyy, faa_status, fnum, hhmmss_ns, latlon
from drivers.nmea.fixstate import (
    ALTITUDE_SET,
    DOP_SET,
    GST_SET,
    LATLON_SET,
    MAGNETIC_TRACK_SET,
    MODE_2D,
    MODE_3D,
    MODE_NO_FIX,
    MODE_SET,
    SPEED_SET,
    STATUS_DGPS,
    STATUS_GPS,
    STATUS_SET,
    STATUS_UNK,
    TIME_SET,
    TRACK_SET,
)

if TYPE_CHECKING:
    from drivers.nmea.session import Session

KNOTS_TO_MPS = 1852.0 / 3600.0
FEET_TO_METERS = 0.3048
# GGA quality -> gpsd status (None: no status)
_GGA_STATUS = {0: 0, 1: 1, 2: 2, 3: 9, 4: 3, 5: 4, 6: 5, 7: 7, 8: 8}


def _timed(st: Session, field: str, mask: int) -> int:
    """Merge a time of day, register it for the cycle detector; TIME_SET once dated."""
    if field and st.merge_hhmmss(field):
        st.last_frac = st.this_frac  # Session.register_time, inline
        st.this_frac = fnum(field)
        st.latch_frac = True
        if st.date is not None:
            return mask | TIME_SET
    return mask


def _int(s: str) -> int:
    """:func:`atoi` with the usual field (plain digits) read at once."""
    return int(s) if s.isdigit() and s.isascii() else atoi(s)


def gga(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    mask = 0
    f0 = f[0]
    last_talker = st.last_gga_talker
    this_talker = st.last_gga_talker = talker[1:2]
    quality = _int(f[5]) if f[5] else -1
    status = _GGA_STATUS.get(quality)
    if quality == 0 and not f0:
        st.time_lost()  # its REPORT/TIME bits are overwritten just below, as in gpsd
    if status is not None:
        new["status"] = status
        mask = STATUS_SET
    latch = st.latch_mode = (
        f0 == st.last_gga_time if not last_talker or last_talker == this_talker else False
    )
    if latch:
        new["status"] = STATUS_UNK
        new["mode"] = MODE_NO_FIX
        mask |= MODE_SET | STATUS_SET
    else:
        st.last_gga_time = f0
    f6 = f[6]
    sats = _int(f6)
    new["used_count"] = sats
    new["quality"] = quality if quality > 0 else 0
    new["gga_sats"] = sats if f6 else None
    mask = _timed(st, f0, mask)
    pos = latlon(f[1], f[2], f[3], f[4])
    if pos is not None:
        new["lat"], new["lon"] = pos
        mode = MODE_2D
        mask |= LATLON_SET
        if f[10]:
            sep = fnum(f[10])
            if sep is not None:
                new["geoid_sep"] = sep
        if f[8]:
            alt = fnum(f[8])
            if alt is not None:
                new["alt_msl"] = alt
            mask |= ALTITUDE_SET
            if sats >= 4:
                mode = MODE_3D
        new["mode"] = MODE_NO_FIX if sats < 3 else mode
    else:
        new["mode"] = MODE_NO_FIX
    mask |= MODE_SET
    hdop = fnum(f[7])
    if hdop is not None and hdop < 99.0:
        new["dop"] = {"hdop": hdop}
        mask |= DOP_SET
    if f[12] and f[13]:
        age, station = fnum(f[12]), atoi(f[13])
        if age is not None and (age > 0.09 or station > 0):
            new["dgps_age"], new["dgps_station"] = age, station
    return mask


def rmc(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    status = f[1][:1]
    mask = 0
    if status != "A" and status != "D":
        new["mode"] = MODE_NO_FIX
        if not f[0] or not f[8]:
            mask |= st.time_lost()
        return mask | STATUS_SET | MODE_SET
    f0 = f[0]
    if f0 and n > 8 and f[8]:
        ok_time = st.merge_hhmmss(f0)
        date = ddmmyy(f[8])
        if ok_time and date is not None:
            st.set_date(date)
            mask |= TIME_SET
            st.last_frac = st.this_frac  # Session.register_time, inline
            st.this_frac = fnum(f0)
            st.latch_frac = True
    pos = latlon(f[2], f[3], f[4], f[5])
    if pos is not None:
        new["lat"], new["lon"] = pos
        newstatus = STATUS_DGPS if status == "D" else STATUS_GPS
        mask |= LATLON_SET
        last_mode = st.lastfix.mode
        if last_mode <= MODE_2D:
            new["mode"] = MODE_2D
            mask |= MODE_SET
        elif last_mode == MODE_3D:
            new["mode"] = MODE_3D
            mask |= MODE_SET
    else:
        newstatus = STATUS_UNK
        new["mode"] = MODE_NO_FIX
        mask |= MODE_SET
    if f[6]:
        speed = fnum(f[6])
        new["speed"] = None if speed is None else speed * KNOTS_TO_MPS
        mask |= SPEED_SET
    if f[7]:
        new["track"] = fnum(f[7])
        mask |= TRACK_SET
    if f[9] and f[10]:
        var = fnum(f[9])
        hemi = f[10][0]
        if var is not None and hemi in "EW" and abs(var) > 0.09:
            new["magvar"] = -var if hemi == "W" else var
            mask |= MAGNETIC_TRACK_SET
    if n >= 11:
        newstatus = faa_status(f[11])
    fix = st.fix
    if st.sky.used_count > 3 or fix.alt_hae is not None or fix.alt_msl is not None:
        new["mode"] = MODE_3D
        mask |= MODE_SET
    new["status"] = newstatus
    return mask | STATUS_SET


def gll(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    mask = 0
    if f[4] and st.merge_hhmmss(f[4]):
        st.register_time(f[4])
        if st.date is not None:
            mask = TIME_SET
    valid = f[5][:1]
    pos = latlon(f[0], f[1], f[2], f[3]) if valid == "A" else None
    if valid == "A" and (n < 7 or f[6][:1] != "N") and pos is not None:
        new["lat"], new["lon"] = pos
        mask |= LATLON_SET
        fix = st.fix
        if fix.alt_hae is not None or fix.alt_msl is not None or st.sky_used() > 3:
            new["mode"] = MODE_3D
        elif fix.mode < MODE_2D or (st.oldfix.alt_hae is None and st.oldfix.alt_msl is None):
            new["mode"] = MODE_2D
        new["status"] = faa_status(f[6]) if n >= 7 else STATUS_GPS
    else:
        new["status"] = STATUS_UNK
        new["mode"] = MODE_NO_FIX
    return mask | STATUS_SET | MODE_SET


def gns(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    mask = _timed(st, f[0], 0)
    faa = f[5][:1]
    if faa in ("", "N"):
        new["mode"] = MODE_NO_FIX
        return mask | MODE_SET
    if f[12][:1] in ("U", "V"):
        return mask
    sats = atoi(f[6])
    new["used_count"] = sats
    pos = latlon(f[1], f[2], f[3], f[4])
    if pos is not None:
        new["lat"], new["lon"] = pos
        new["mode"] = MODE_2D
        mask |= LATLON_SET
        if f[8]:
            alt = fnum(f[8])
            if alt is not None:
                new["alt_msl"] = alt
                mask |= ALTITUDE_SET
                if sats > 3:
                    new["mode"] = MODE_3D
            sep = fnum(f[9]) if f[9] else None
            if sep is not None:
                new["geoid_sep"] = sep
    else:
        new["mode"] = MODE_NO_FIX
    hdop = fnum(f[7])
    if hdop is not None:
        new["dop"] = {"hdop": hdop}
        mask |= DOP_SET
    new["status"] = faa_status(faa)
    if f[10] and f[11]:
        age = fnum(f[10])
        if age is not None:
            new["dgps_age"], new["dgps_station"] = age, atoi(f[11])
    return mask | MODE_SET | STATUS_SET


def vtg(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    if not f[0] or not f[4]:
        return 0
    if n > 8 and f[8][:1] in ("E", "N"):
        return 0
    new["track"] = fnum(f[0])
    mask = TRACK_SET | SPEED_SET
    if f[2]:
        magtrack = fnum(f[2])
        if magtrack is not None:
            new["magtrack"] = magtrack
        mask |= MAGNETIC_TRACK_SET
    speed = fnum(f[4])
    new["speed"] = None if speed is None else speed * KNOTS_TO_MPS
    return mask


def gst(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    st.gst = tuple(map(fnum, f[1:8]))
    st.gst_tod = hhmmss_ns(f[0])
    return GST_SET


def zda(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    f0, f1, f2, f3 = f[0], f[1], f[2], f[3]
    if not (f0 and f1 and f2 and f3):
        return 0
    if not st.merge_hhmmss(f0):
        return 0
    d, m, y = _int(f1), _int(f2), _int(f3)
    if not (1900 <= y <= 2200 and 1 <= m <= 12 and 1 <= d <= 31) or len(f3) != 4:
        st.malformed += 1
        return 0
    st.set_date((y, m, d))
    return TIME_SET


def gbs(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    """GBS: error estimates (1 sigma) of the fix of the same second."""
    if f[0]:
        st.register_time(f[0])
    if st.tod_ns is None or f[0][:6] != st.hhmmss():
        return 0
    new["epy"], new["epx"], new["epv"] = fnum(f[1]), fnum(f[2]), fnum(f[3])
    for k in ("epx", "epy", "epv"):
        if new[k] is None:
            del new[k]
    return 0
