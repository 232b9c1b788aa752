"""The fast path's readers of the sentences that give the position: GGA, RMC and GLL.

Same contract as :mod:`drivers.nmea.fastpath` (the other readers, and the rules they
share): the ordinary sentence read and merged in one pass, anything else the reference
way (Session.parse / Session.apply, with handlers.gga, handlers.rmc and handlers.gll)
before any state changes. GGA and RMC start a new cycle when their time of day differs
from the last one registered, which ends the epoch (EpochCombiner.new_epoch) before their
data is merged; a GLL that would start one takes the reference path.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivers.nmea.errmodel import error_model, motion_model
from drivers.nmea.fastpath import (
    _DATES,
    _NONE,
    _TIMES,
    HOUR_NS,
    _date,
    _time,
    gsa,
    gst,
    gsv,
    reference,
    vtg,
    zda,
)
from drivers.nmea.fields import _FAA, atoi, fnum, latlon, read_number
from drivers.nmea.fields import NUMBERS as nums
from drivers.nmea.fixstate import (
    MODE_2D,
    MODE_3D,
    MODE_NO_FIX,
    MODE_NOT_SEEN,
    STATUS_GPS,
    gga_fix,
    rmc_fix,
)
from drivers.nmea.handlers import _GGA_STATUS, KNOTS_TO_MPS
from drivers.nmea.session import DAY_NS, ROLLOVER_S

if TYPE_CHECKING:
    from collections.abc import Callable

    from drivers.nmea.epoch import EpochCombiner
    from drivers.nmea.fixstate import Fix
    from drivers.nmea.session import Session

# GGA quality field -> (quality, gpsd status)
_QUALITY = {str(q): (q, s) for q, s in _GGA_STATUS.items()}


def gga(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    f = rest.split(",")
    if len(f) < 14:
        return reference(rest, stamp, out, comb, talker, "GGA")
    st = comb.session
    f0, f6 = f[0], f[6]
    q = _QUALITY.get(f[5])
    if q is None or not f0 or not f6.isdigit():
        return reference(rest, stamp, out, comb, talker, "GGA")
    this_talker = talker[1:2]
    last_talker = st.last_gga_talker
    if f0 == st.last_gga_time and (not last_talker or last_talker == this_talker):
        return reference(rest, stamp, out, comb, talker, "GGA")  # latched: no fix
    ns, frac = _TIMES.get(f0) or _time(f0)
    if ns is None:
        return reference(rest, stamp, out, comb, talker, "GGA")
    pos = latlon(f[1], f[2], f[3], f[4])
    if pos is None:
        return reference(rest, stamp, out, comb, talker, "GGA")
    # --- the ordinary GGA from here on (Session.parse, handlers.gga)
    quality, status = q
    sats = int(f6)
    st.last_gga_talker = this_talker
    st.latch_mode = False
    st.last_gga_time = f0
    tod = st.tod_ns
    if tod is not None and ns < tod and ns // HOUR_NS < tod // HOUR_NS:
        st.day += 1  # (Session.merge_hhmmss: the hour went back, past midnight)
    st.tod_ns = ns
    last = st.last_frac = st.this_frac
    st.this_frac = frac
    st.latch_frac = True
    st.gsx_more = False
    sky = st.sky
    sky.last_gsv_talker = sky.last_gsa_talker = ""
    lat, lon = pos
    f8 = f[8]
    if f8:
        alt = nums.get(f8) or read_number(f8)
        mode = MODE_3D if sats >= 4 else 2
    else:
        alt = None
        mode = 2
    f10 = f[10]
    sep = (nums.get(f10) or read_number(f10)) if f10 else None
    if sats < 3:
        mode = MODE_NO_FIX
    hdop = nums.get(f[7]) or read_number(f[7])
    if hdop is not None and not hdop < 99.0:
        hdop = None
    age = station = None
    if f[12] and f[13]:
        age, station = fnum(f[12]), atoi(f[13])
        if age is None or not (age > 0.09 or station > 0):
            age = station = None
    fix = st.fix
    if mode == 2 and fix.mode == MODE_3D and st._had_altitude():
        mode = MODE_3D
    time_ns = None if st.date is None else st.day * DAY_NS + ns
    # --- EpochCombiner.add_into and Session.apply
    if frac is None or last is None or abs(frac - last) > 0.01:  # a new cycle (Session.parse)
        _new_epoch(comb, out)
        comb._pending = True
        comb._snap = None
        if hdop is None:
            sky.dop.clear()
        else:
            sky.dop["hdop"] = hdop
        st.fix = gga_fix(time_ns, lat, lon, alt, sep, mode, status, age, station)
        st.quality, st.gga_sats = quality, sats
        if sky.used_count != sats:
            sky.used_count = sats
            sky.changed = True
        error_model(st, _NONE)
    else:
        comb._pending = True
        comb._snap = None
        changed = _merge(st, fix, time_ns, lat, lon, mode, status)
        if hdop is not None:
            sky.dop["hdop"] = hdop
        st.quality, st.gga_sats = quality, sats
        if sky.used_count != sats:
            sky.used_count = sats
            sky.changed = True
        if sep is not None and fix.geoid_sep != sep:
            fix.geoid_sep = sep
            changed = True
        if alt is not None and fix.alt_msl != alt:
            fix.alt_msl = alt
            changed = True
        if age is not None and (fix.dgps_age != age or fix.dgps_station != station):
            fix.dgps_age, fix.dgps_station = age, station
            changed = True
        if changed or sky.dop != st._dops or st._unnormed:
            error_model(st, _NONE)
    comb._stamp_ns = stamp
    comb._talker = talker
    comb.timed("GGA", out)


def _motion(st: Session, fix: Fix, unknown_speed: bool) -> None:
    """The error model after a change of speed or tracks alone (errmodel.motion_model,
    when its conditions hold: no velocities, the speed not made unknown)."""
    if unknown_speed or fix.vel_n is not None or fix.vel_e is not None or fix.vel_d is not None:
        error_model(st, _NONE)
    else:
        motion_model(st)


def _new_epoch(comb: EpochCombiner, out: list) -> None:
    """EpochCombiner.new_epoch (and _close): the last epoch's fix and sky if not reported."""
    if comb._pending:
        comb._report(out)
    elif comb.session.sky.changed:
        out.append(comb._sky())
    comb._last_fix = None
    comb._ender = comb._last_timed
    comb._last_timed = None
    comb._reported = False


def _merge(st: Session, fix: Fix, time_ns, lat: float, lon: float, mode: int, status: int) -> bool:
    """merge's comparisons of a position sentence's time (None: it sets none), position,
    mode and status (upwards only) with the fix's, which takes what differs; whether
    anything did. A time of 0 leaves the last fix as it was (Session.apply's copy)."""
    changed = False
    if time_ns is not None:
        if not time_ns and st.lastfix is fix:
            st.lastfix = fix.copy()
        if fix.time_ns != time_ns:
            fix.time_ns = time_ns
            changed = True
    if fix.lat != lat:
        fix.lat = lat
        changed = True
    if fix.lon != lon:
        fix.lon = lon
        changed = True
    if fix.mode != mode:
        fix.mode = mode
        changed = True
    if fix.status < status:
        fix.status = status
        changed = True
    return changed


def rmc(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    f = rest.split(",")
    n = len(f)
    if n < 11:
        return reference(rest, stamp, out, comb, talker, "RMC")
    status = f[1]
    f0, f8 = f[0], f[8]
    if (status != "A" and status != "D") or not f0 or not f8:
        return reference(rest, stamp, out, comb, talker, "RMC")
    st = comb.session
    ns, frac = _TIMES.get(f0) or _time(f0)
    date = _DATES.get(f8) or _date(f8)
    if ns is None or not date:
        return reference(rest, stamp, out, comb, talker, "RMC")
    pos = latlon(f[2], f[3], f[4], f[5])
    last_mode = st.lastfix.mode
    if pos is None or last_mode > MODE_3D:  # (a GSA may give any number as the mode)
        return reference(rest, stamp, out, comb, talker, "RMC")
    # --- the ordinary RMC from here on (Session.parse, handlers.rmc)
    st.gsx_more = False
    st.tod_ns = ns  # (a midnight wrap of the day is overridden by the date just below)
    ymd, day = date
    st.date = ymd
    if st.rollover_before_year is not None and ymd[0] < st.rollover_before_year:
        day += ROLLOVER_S // 86400
    st.day = day
    last = st.last_frac = st.this_frac
    st.this_frac = frac
    st.latch_frac = True
    lat, lon = pos
    f6 = f[6]
    speed_set = bool(f6)
    speed = None
    if speed_set:
        speed = nums.get(f6) or read_number(f6)
        if speed is not None:
            speed *= KNOTS_TO_MPS
    f7 = f[7]
    track_set = bool(f7)
    track = (nums.get(f7) or read_number(f7)) if track_set else None
    magvar = None
    if f[9] and f[10]:
        var = fnum(f[9])
        hemi = f[10][0]
        if var is not None and hemi in "EW" and abs(var) > 0.09:
            magvar = -var if hemi == "W" else var
    newstatus = _FAA.get(f[11][:1], 1) if n > 11 else 0  # (fields.faa_status)
    fix = st.fix
    sky = st.sky
    # 3D: after a 3D fix, with more than 3 satellites or an altitude, or as a 3D fix that
    # had an altitude (Session.parse: RMC says nothing of 3D)
    mode = (
        MODE_3D
        if last_mode == MODE_3D
        or sky.used_count > 3
        or fix.alt_hae is not None
        or fix.alt_msl is not None
        or (fix.mode == MODE_3D and st._had_altitude())
        else 2
    )
    sky.last_gsv_talker = sky.last_gsa_talker = ""
    time_ns = day * DAY_NS + ns
    # --- EpochCombiner.add_into and Session.apply
    if frac is None or last is None or abs(frac - last) > 0.01:  # a new cycle (Session.parse)
        _new_epoch(comb, out)
        comb._pending = True
        comb._snap = None
        sky.dop.clear()
        st.fix = rmc_fix(time_ns, lat, lon, speed, track, magvar, mode, newstatus)
        st.quality = st.gga_sats = None
        error_model(st, _NONE)
    else:
        comb._pending = True
        comb._snap = None
        changed = _merge(st, fix, time_ns, lat, lon, mode, newstatus)
        moved = False  # (the speed, track or variation changed)
        if speed_set and fix.speed != speed:
            fix.speed = speed
            moved = True
        if track_set and fix.track != track:
            fix.track = track
            moved = True
        if magvar is not None and fix.magvar != magvar:
            fix.magvar = magvar
            moved = True
        if changed or sky.dop != st._dops or st._unnormed:
            error_model(st, _NONE)
        elif moved:
            _motion(st, fix, speed_set and speed is None)
    comb._stamp_ns = stamp
    comb._talker = talker
    comb.timed("RMC", out)


def gll(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    """A valid GLL (A, a position and a time) of an epoch under way; any other the
    reference way (a GLL that starts a cycle too)."""
    f = rest.split(",")
    n = len(f)
    if n < 6:
        return reference(rest, stamp, out, comb, talker, "GLL")
    f4 = f[4]
    if not f4 or f[5][:1] != "A" or (n >= 7 and f[6][:1] == "N"):
        return reference(rest, stamp, out, comb, talker, "GLL")
    st = comb.session
    ns, frac = _TIMES.get(f4) or _time(f4)
    last = st.this_frac
    if ns is None or frac is None or last is None or abs(frac - last) > 0.01:
        return reference(rest, stamp, out, comb, talker, "GLL")  # (no time, a new cycle)
    pos = latlon(f[0], f[1], f[2], f[3])
    if pos is None:
        return reference(rest, stamp, out, comb, talker, "GLL")
    # --- the ordinary GLL from here on (Session.parse, handlers.gll)
    tod = st.tod_ns
    if tod is not None and ns < tod and ns // HOUR_NS < tod // HOUR_NS:
        st.day += 1  # (Session.merge_hhmmss: the hour went back, past midnight)
    st.tod_ns = ns
    st.last_frac = last
    st.this_frac = frac
    st.latch_frac = True
    st.gsx_more = False
    sky = st.sky
    sky.last_gsv_talker = sky.last_gsa_talker = ""
    fix = st.fix
    old = st.oldfix
    if fix.alt_hae is not None or fix.alt_msl is not None or sky.used_count > 3:
        mode = MODE_3D
    elif fix.mode < MODE_2D or (old.alt_hae is None and old.alt_msl is None):
        mode = MODE_2D
    else:
        mode = MODE_NOT_SEEN  # (the GLL gives no mode: merge's default)
    if fix.mode == MODE_3D and st._had_altitude():
        mode = MODE_3D  # (Session.parse: not dropped from 3D)
    status = _FAA.get(f[6][:1], 1) if n >= 7 else STATUS_GPS  # (fields.faa_status)
    lat, lon = pos
    # --- EpochCombiner.add_into and Session.apply
    comb._pending = True
    comb._snap = None
    time_ns = None if st.date is None else st.day * DAY_NS + ns
    if _merge(st, fix, time_ns, lat, lon, mode, status) or sky.dop != st._dops or st._unnormed:
        error_model(st, _NONE)
    comb._stamp_ns = stamp
    comb._talker = talker
    comb.timed("GLL", out)


# type -> its fast reader (the talker does not matter; proprietary sentences have none)
FAST: dict[str, Callable[..., None]] = {
    "GGA": gga,
    "RMC": rmc,
    "GLL": gll,
    "GSA": gsa,
    "GSV": gsv,
    "VTG": vtg,
    "GST": gst,
    "ZDA": zda,
}
