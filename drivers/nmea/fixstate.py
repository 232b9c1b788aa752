"""The fix being built from NMEA sentences, and how a sentence's data merges into it.

:class:`Fix` holds the fields of gpsd's ``gps_fix_t`` that NMEA can fill (None where gpsd
has NaN). A sentence handler fills a fresh ``dict`` (gpsd's ``newdata``) and returns a
mask of what it set; :func:`merge` copies the data into the current fix following gpsd's
``gps_merge_fix``: position, mode, track and speed only when their bit is set, status
only upwards, altitudes and error estimates whenever the handler gave them.
"""

from __future__ import annotations

# Mask bits (what a sentence set; gpsd's gps_mask_t, the ones NMEA uses).
TIME_SET = 1 << 0
LATLON_SET = 1 << 1
MODE_SET = 1 << 2
STATUS_SET = 1 << 3
ALTITUDE_SET = 1 << 4
TRACK_SET = 1 << 5
MAGNETIC_TRACK_SET = 1 << 6
SPEED_SET = 1 << 7
CLIMB_SET = 1 << 8
VNED_SET = 1 << 9
DOP_SET = 1 << 10
USED_IS = 1 << 11
SATELLITE_SET = 1 << 12
GST_SET = 1 << 13
CLEAR_IS = 1 << 14
REPORT_IS = 1 << 15

# Fix modes and statuses (gpsd's numbering).
MODE_NOT_SEEN, MODE_NO_FIX, MODE_2D, MODE_3D = 0, 1, 2, 3
STATUS_UNK, STATUS_GPS, STATUS_DGPS, STATUS_RTK_FIX, STATUS_RTK_FLT = 0, 1, 2, 3, 4
STATUS_DR, STATUS_GNSSDR, STATUS_TIME, STATUS_SIM, STATUS_PPS_FIX = 5, 6, 7, 8, 9

FIELDS = (
    "time_ns", "lat", "lon", "alt_hae", "alt_msl", "mode", "status", "track", "magtrack",
    "magvar", "speed", "climb", "ept", "epx", "epy", "epd", "eph", "eps", "sep", "geoid_sep",
    "epv", "epc", "vel_n", "vel_e", "vel_d", "dgps_age", "dgps_station",
)  # fmt: skip


class Fix:
    """gpsd's fix record (None = not known). ``time_ns``: UTC, ns since 1970."""

    __slots__ = FIELDS

    def __init__(self) -> None:
        for name in FIELDS:
            setattr(self, name, None)
        self.mode = MODE_NOT_SEEN
        self.status = STATUS_UNK

    def copy(self) -> Fix:
        c = Fix.__new__(Fix)
        for name in FIELDS:
            setattr(c, name, getattr(self, name))
        return c

    def snapshot(self) -> Snapshot:
        """The fields the next sentences and epochs look back at (gpsd's lastfix/oldfix)."""
        return Snapshot(self)


class Snapshot:
    """A copy of the fields of a :class:`Fix` that later computations read."""

    __slots__ = ("time_ns", "mode", "lat", "lon", "alt_hae", "alt_msl", "epx", "epy", "epv")

    def __init__(self, f: Fix | None = None) -> None:
        if f is None:
            self.time_ns = self.lat = self.lon = self.alt_hae = self.alt_msl = None
            self.epx = self.epy = self.epv = None
            self.mode = MODE_NOT_SEEN
        else:
            self.time_ns, self.mode, self.lat, self.lon = f.time_ns, f.mode, f.lat, f.lon
            self.alt_hae, self.alt_msl, self.epx, self.epy, self.epv = (
                f.alt_hae, f.alt_msl, f.epx, f.epy, f.epv
            )  # fmt: skip


# Fields copied whenever the handler gave them (no mask bit), as gps_merge_fix does.
_ALWAYS = ("epd", "eph", "eps", "sep", "geoid_sep", "epv")


def merge(to: Fix, mask: int, new: dict) -> None:
    """Merge one sentence's data (``new``, set under ``mask``) into the fix ``to``."""
    get = new.get
    if mask & TIME_SET:
        to.time_ns = get("time_ns")
    if mask & LATLON_SET:
        to.lat = get("lat")
        to.lon = get("lon")
    if mask & MODE_SET:
        to.mode = get("mode", MODE_NOT_SEEN)
    if mask & STATUS_SET:
        status = get("status", STATUS_UNK)
        if to.status < status:
            to.status = status
    if mask & ALTITUDE_SET:
        if "alt_hae" in new:
            to.alt_hae = new["alt_hae"]
        if "alt_msl" in new:
            to.alt_msl = new["alt_msl"]
    if mask & TRACK_SET:
        to.track = get("track")
    if mask & MAGNETIC_TRACK_SET:
        if "magtrack" in new:
            to.magtrack = new["magtrack"]
        if "magvar" in new:
            to.magvar = new["magvar"]
    if mask & SPEED_SET:
        to.speed = get("speed")
    if mask & CLIMB_SET:
        to.climb = get("climb")
    if mask & VNED_SET:
        to.vel_n, to.vel_e, to.vel_d = get("vel_n"), get("vel_e"), get("vel_d")
    for name in _ALWAYS:
        if name in new:
            setattr(to, name, new[name])
    if "epx" in new and "epy" in new:
        to.epx, to.epy = new["epx"], new["epy"]
    if "dgps_age" in new:
        to.dgps_age, to.dgps_station = new["dgps_age"], new["dgps_station"]
