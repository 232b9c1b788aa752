"""Report NMEA epochs as :class:`msgs.GpsFix` (gpsd's TPV) and :class:`msgs.GpsSky` (SKY).

The sentences go through a :class:`~drivers.nmea.session.Session`, which keeps the fix
as gpsd would (mode from the last sentence that sets one, position from the last sentence
that gives one, GSA's mode over GGA's, altitude from GGA, GNS or PGRMZ, error estimates,
climb, ...). An epoch ends where gpsd's does: at a sentence whose time of day differs from
the last one registered.

When: the fix is reported at the epoch's "cycle ender", the type of the last timed
sentence of the previous epoch (learned as gpsd learns it), so a live stream reports each
fix without waiting a whole period. An epoch not reported that way (the first one, or an
irregular receiver), or changed after its ender by a sentence that sets fix data (a GSA's
mode, a PGRMZ altitude), is reported (again) when the next epoch starts or at
:meth:`EpochCombiner.flush`. Sentences gpsd reports no fix for (a GSV set, PGRME, GBS)
after that do not change the epoch's report, as they do not change gpsd's last one. The
sky is reported with the fix when a GGA, a GSA or a complete GSV set changed it, or when
the epoch ends.

What: a GpsFix holds what gpsd's TPV would print: position, altitudes, track, speed and
error estimates only with a fix (mode 2 or 3), climb, geoid separation and vertical
velocity only in 3D; the time only once a date is known (RMC, ZDA). ``quality`` is the
epoch's GGA fix quality (without a GGA: 1 with a fix, else 0); ``satellites`` the GGA's
count, else the number used gpsd keeps (GSA's or an earlier GGA's); ``std_*`` and the
``gst_*`` fields come from a GST of the same second. Local metres are about the
configured datum, or the first fix's position when none is configured.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import fields as dataclass_fields
from operator import attrgetter

from drivers.nmea.fixstate import (
    ALTITUDE_SET,
    CLEAR_IS,
    CLIMB_SET,
    DEFERRED,
    LATLON_SET,
    MAGNETIC_TRACK_SET,
    MODE_2D,
    MODE_3D,
    MODE_SET,
    SATELLITE_SET,
    SPEED_SET,
    STATUS_SET,
    TIME_SET,
    TRACK_SET,
    VNED_SET,
    Fix,
)
from drivers.nmea.local import Datum
from drivers.nmea.memo import on_clear, table
from drivers.nmea.session import DAY_NS, ROLLOVER_S, Session
from msgs import GpsFix, GpsSky
from msgs.construct import expression_constructor, positional_constructor

__all__ = ["ROLLOVER_S", "EpochCombiner", "iso_time"]

# Sentences whose time of day marks their place in the cycle (gpsd's cycle enders).
_TIMED = frozenset(("GGA", "RMC", "GLL", "GNS", "GBS", "ZDA", "PSTI", "PGRMF"))
_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
# What a sentence must set for its epoch to have a fix to report.
_FIX_BITS = (TIME_SET | LATLON_SET | MODE_SET | STATUS_SET | ALTITUDE_SET | TRACK_SET
             | MAGNETIC_TRACK_SET | SPEED_SET | CLIMB_SET | VNED_SET)  # fmt: skip


_DAYS: dict[int, str] = table({})
_LAST: list = [None, ""]  # the last time formatted (a fix and its sky share it)


def _forget_last() -> None:
    _LAST[:] = [None, ""]


on_clear(_forget_last)


def iso_time(ns: int | None) -> str:
    """ISO 8601 UTC with milliseconds, rounded as gpsd rounds; "" for None or out of range."""
    if ns is None or ns < 0:
        return ""
    if ns == _LAST[0]:
        return _LAST[1]
    ms = (ns + 500_000) // 1_000_000
    day, ms_of_day = divmod(ms, 86_400_000)
    date = _DAYS.get(day)
    if date is None:
        try:
            t = _EPOCH + dt.timedelta(days=day)
        except OverflowError:
            return ""
        if t.year > 9999:
            return ""
        date = _DAYS[day] = f"{t.year:04d}-{t.month:02d}-{t.day:02d}T"
        if len(_DAYS) > 64:
            _DAYS.clear()
    s, milli = divmod(ms_of_day, 1000)
    m, s = divmod(s, 60)
    text = _LAST[1] = date + _HHMM[m] + _SS[s] + _MMM[milli]
    _LAST[0] = ns
    return text


# the pieces of a time of day: "hh:mm:" of each minute, "ss." of each second, "mmmZ"
_HHMM = tuple(f"{m // 60:02d}:{m % 60:02d}:" for m in range(1440))
_SS = tuple(f"{s:02d}." for s in range(61))
_MMM = tuple(f"{ms:03d}Z" for ms in range(1000))


# What a fix without a 2D (3D) fix, or a GST of another second, shows: nothing.
_make_sky = positional_constructor(GpsSky)
# a fix's fields but its stamp, as a tuple (what the dataclass's == compares)
_but_stamp = attrgetter(*(f.name for f in dataclass_fields(GpsFix) if f.name != "stamp_ns"))
_NO_GST = (None,) * 7
_prn = attrgetter("prn")


class EpochCombiner:
    """Feed sentences in order; get fixes and skies back (see module docstring)."""

    def __init__(self, datum: Datum | None = None, rollover_before_year: int | None = None) -> None:
        self.datum = datum
        self.session = Session(rollover_before_year)
        self._ender: str | None = None
        self._last_timed: str | None = None
        self._reported = False
        self._pending = False  # the epoch has sentences not yet reported
        self._last_fix: GpsFix | None = None  # this epoch's last reported fix
        self._snap: Fix | None = None  # the fix before sentences gpsd does not report
        self._stamp_ns = 0
        self._talker = ""

    @property
    def rollover_before_year(self) -> int | None:
        return self.session.rollover_before_year

    def add(self, talker: str, kind: str, fields: tuple[str, ...], stamp_ns: int) -> list:
        """One sentence (``kind`` "GGA", ...; proprietary ones "PGRMZ") -> messages."""
        out: list = []
        self.add_into(talker, kind, fields, stamp_ns, out)
        return out

    def add_into(
        self, talker: str, kind: str, fields: tuple[str, ...], stamp_ns: int, out: list
    ) -> None:
        """:meth:`add`, appending the messages to ``out``."""
        st = self.session
        mask, new = st.parse(talker, kind, fields)
        if mask & CLEAR_IS:
            self.new_epoch(out)
        worthy = mask & _FIX_BITS
        if worthy:
            self._pending = True
            self._snap = None
        elif self._pending and self._snap is None and (mask & SATELLITE_SET or new):
            self._snap = st.fix.copy()  # the fix as gpsd last reported it (see module doc)
        st.apply(mask, new)
        self._stamp_ns = stamp_ns
        if kind != "GSV" and kind != "GSA":
            self._talker = talker
        if kind in _TIMED and (st.latch_frac or (kind == "ZDA" and "time_ns" in new)):
            self.timed(kind, out)

    def new_epoch(self, out: list) -> None:
        """A sentence starts a new cycle: the last epoch ends (before its data is merged)."""
        self._close(out)
        self._ender = self._last_timed
        self._last_timed = None
        self._reported = False

    def timed(self, kind: str, out: list) -> None:
        """A sentence of type ``kind`` gave this epoch's time: the fix if it ends the cycle."""
        self._last_timed = kind
        if kind == self._ender and not self._reported:
            self._report(out)

    def flush(self) -> list:
        """The pending epoch's fix and sky (end of a stream), if not reported yet."""
        out: list = []
        self._close(out)
        return out

    # ------------------------------------------------------------------
    def _close(self, out: list) -> None:
        """The end of an epoch: its fix if not reported, or reported before later sentences
        of the epoch changed it; its sky if it changed."""
        if self._pending:
            self._report(out)
        elif self.session.sky.changed:
            out.append(self._sky())
        self._last_fix = None

    def _report(self, out: list) -> None:
        """The epoch's fix (unless it is the one reported last) and its sky if changed."""
        st = self.session
        f = self._snap or st.fix
        self._snap = None
        mode = f.mode
        t = f.time_ns
        gst = st.gst
        if gst is None or t is None or st.gst_tod != t % DAY_NS:
            gst = _NO_GST
        quality = st.quality
        if quality is None:
            quality = 1 if mode >= MODE_2D else 0
        sky = st.sky
        sats = st.gga_sats
        if sats is None:
            sats = sky.used_count or None
        ept = f.ept if t is not None else None
        # what a fix shows: the position and its kin with a 2D fix, the rest in 3D only
        if mode >= MODE_2D:
            lat, lon = f.lat, f.lon
            east = north = None
            if lat is not None and lon is not None:
                datum = self.datum
                if datum is None:
                    datum = self.datum = Datum(lat, lon)
                east, north = datum.to_local(lat, lon)
            speed = f.speed
            if speed is DEFERRED:
                speed = f.speed_now()
            fix = (_fix_3d if mode >= MODE_3D else _fix_2d)(
                f, self._stamp_ns, iso_time(t), quality, sats, sky.dop, gst, east, north,
                self._talker, speed, ept, st.leap_seconds,
            )  # fmt: skip
        else:
            fix = _fix_none(
                f, self._stamp_ns, iso_time(t), quality, sats, sky.dop, gst, None, None,
                self._talker, None, ept, st.leap_seconds,
            )  # fmt: skip
        last = self._last_fix
        if last is None or _but_stamp(last) != _but_stamp(fix):  # (replace(...) != fix)
            out.append(fix)
            self._last_fix = fix
        if sky.changed:
            out.append(self._sky())
        self._reported = True
        self._pending = False

    def _sky(self) -> GpsSky:
        st = self.session
        sky = st.sky
        sky.changed = False
        sats = tuple(filter(_prn, sky.view))  # (the view holds the messages; PRN 0: none)
        get = sky.dop.get
        return _make_sky(
            self._stamp_ns, iso_time(st.fix.time_ns), sats, len(sats) if sky.complete else None,
            sky.used_count, get("hdop"), get("vdop"), get("pdop"), get("xdop"), get("ydop"),
            get("tdop"), get("gdop"), self._talker,
        )  # fmt: skip


# A GpsFix of a Fix f (the fields' names differ: lat_deg is f.lat, ...), by mode: the
# values every fix shows, those shown with a 2D fix, and those shown in 3D only.
_SHOWN = {
    "stamp_ns": "stamp", "time_utc": "time_utc", "mode": "f.mode", "quality": "quality",
    "satellites": "sats", "hdop": "dop.get('hdop')", "pdop": "dop.get('pdop')",
    "vdop": "dop.get('vdop')", "std_lat_m": "gst[4]", "std_lon_m": "gst[5]",
    "std_alt_m": "gst[6]", "east_m": "east", "north_m": "north", "talker": "talker",
    "status": "f.status", "ept_s": "ept", "leap_seconds": "leap", "gst_rms_m": "gst[0]",
    "gst_major_m": "gst[1]", "gst_minor_m": "gst[2]", "gst_orient_deg": "gst[3]",
}  # fmt: skip
_SHOWN_2D = {
    "lat_deg": "f.lat", "lon_deg": "f.lon", "alt_msl_m": "f.alt_msl", "speed_mps": "speed",
    "course_deg": "f.track", "alt_hae_m": "f.alt_hae", "eph_m": "f.eph", "epv_m": "f.epv",
    "epx_m": "f.epx", "epy_m": "f.epy", "sep_m": "f.sep", "eps_mps": "f.eps",
    "epd_deg": "f.epd", "magvar_deg": "f.magvar", "magtrack_deg": "f.magtrack",
    "dgps_age_s": "f.dgps_age", "dgps_station": "f.dgps_station",
}  # fmt: skip
_SHOWN_3D = {
    "geoid_sep_m": "f.geoid_sep", "climb_mps": "f.climb", "epc_mps": "f.epc",
    "vel_n_mps": "f.vel_n", "vel_e_mps": "f.vel_e", "vel_d_mps": "f.vel_d",
}  # fmt: skip
_FIX_PARAMS = "f, stamp, time_utc, quality, sats, dop, gst, east, north, talker, speed, ept, leap"
_none = dict.fromkeys(_SHOWN_2D | _SHOWN_3D, "None")
_fix_3d = expression_constructor(GpsFix, _FIX_PARAMS, _SHOWN | _SHOWN_2D | _SHOWN_3D)
_fix_2d = expression_constructor(
    GpsFix, _FIX_PARAMS, _SHOWN | _SHOWN_2D | dict.fromkeys(_SHOWN_3D, "None")
)
_fix_none = expression_constructor(GpsFix, _FIX_PARAMS, _SHOWN | _none)
