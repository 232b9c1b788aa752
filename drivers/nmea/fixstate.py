"""The fix being built from NMEA sentences, and how a sentence's data merges into it.

:class:`Fix` holds the fields of gpsd's ``gps_fix_t`` that NMEA can fill (None where gpsd
has NaN). A sentence handler fills a fresh ``dict`` (gpsd's ``newdata``) and returns a
mask of what it set; :func:`merge` copies the data into the current fix following gpsd's
``gps_merge_fix``: position, mode, track and speed only when their bit is set, status
only upwards, altitudes and error estimates whenever the handler gave them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

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

# The speed of a fix whose speed is the distance from the previous fix over the time
# between them: computed only when the fix is reported (usually a later sentence of the
# epoch gives the receiver's own speed first). Not None, so gpsd's "speed known" holds.
DEFERRED = float("nan")


FIELDS = (
    "time_ns", "lat", "lon", "alt_hae", "alt_msl", "track", "magtrack", "magvar", "speed",
    "climb", "ept", "epx", "epy", "epd", "eph", "eps", "sep", "geoid_sep", "epv", "epc",
    "vel_n", "vel_e", "vel_d", "dgps_age", "dgps_station", "speed_args", "mode", "status",
)  # fmt: skip


class Fix:
    """gpsd's fix record (None = not known). ``time_ns``: UTC, ns since 1970.

    Slotted: the error model and the report read most fields of the fix after every
    sentence that changes it, and a slot is the cheapest read there is."""

    __slots__ = FIELDS

    def __init__(self) -> None:
        self.time_ns = self.lat = self.lon = self.alt_hae = self.alt_msl = self.track = None
        self.magtrack = self.magvar = self.speed = self.climb = self.ept = self.epx = None
        self.epy = self.epd = self.eph = self.eps = self.sep = self.geoid_sep = None
        self.epv = self.epc = self.vel_n = self.vel_e = self.vel_d = self.dgps_age = None
        self.dgps_station = self.speed_args = None
        self.mode = MODE_NOT_SEEN
        self.status = STATUS_UNK

    def speed_now(self) -> float | None:
        """The speed, the deferred distance / time computed now."""
        if self.speed is DEFERRED:
            from drivers.nmea.errmodel import deferred_speed

            self.speed = deferred_speed(*self.speed_args)
        return self.speed

    def copy(self) -> Fix:
        return _copy(self)


def _copier() -> Callable[[Fix], Fix]:
    """A function copying every field of a fix (written out: one slot read and one slot
    write per field)."""
    body = "".join(f"    c.{name} = f.{name}\n" for name in FIELDS)
    env: dict[str, Any] = {"_new": object.__new__, "Fix": Fix}
    exec(f"def copy(f):\n    c = _new(Fix)\n{body}    return c\n", env)
    return env["copy"]


_copy = _copier()


def _fresh(*given: str) -> Callable[..., Fix]:
    """A function ``f(*given)``: a new fix (as ``Fix()``) with the fields ``given`` set to
    its arguments (written out: one slot write per field)."""
    body = "".join(
        f"    f.{name} = {name if name in given else 'None'}\n"
        for name in FIELDS
        if name not in ("mode", "status") or name in given
    )
    if "mode" not in given:
        body += "    f.mode = MODE_NOT_SEEN\n"
    if "status" not in given:
        body += "    f.status = STATUS_UNK\n"
    env: dict[str, Any] = {"_new": object.__new__, "Fix": Fix, "MODE_NOT_SEEN": MODE_NOT_SEEN,
                           "STATUS_UNK": STATUS_UNK}  # fmt: skip
    exec(f"def fresh({', '.join(given)}):\n    f = _new(Fix)\n{body}    return f\n", env)
    return env["fresh"]


# the fix a new cycle starts with, as a GGA or an RMC leaves it (Fix() and their merge)
gga_fix = _fresh("time_ns", "lat", "lon", "alt_msl", "geoid_sep", "mode", "status",
                 "dgps_age", "dgps_station")  # fmt: skip
rmc_fix = _fresh("time_ns", "lat", "lon", "speed", "track", "magvar", "mode", "status")


# new-data key -> the mask bit it needs (0: copied whenever given). Every handler gives a
# key only with its bit set (tests/test_nmea_gpsd.py checks it), so merge() copies the keys
# without looking at the bits; the table documents the rule and is what the test checks.
GATE = {
    "time_ns": TIME_SET, "lat": LATLON_SET, "lon": LATLON_SET, "alt_hae": ALTITUDE_SET,
    "alt_msl": ALTITUDE_SET, "track": TRACK_SET, "magtrack": MAGNETIC_TRACK_SET,
    "magvar": MAGNETIC_TRACK_SET, "speed": SPEED_SET, "climb": CLIMB_SET, "vel_n": VNED_SET,
    "vel_e": VNED_SET, "vel_d": VNED_SET, "epd": 0, "eph": 0, "eps": 0, "sep": 0,
    "geoid_sep": 0, "epv": 0,
}  # fmt: skip
# keys of new data with rules of their own (below), or the session's (DOPs, GGA's counts)
SPECIAL = frozenset(("mode", "status", "epx", "epy", "dgps_age", "dgps_station", "dop",
                     "quality", "gga_sats", "used_count"))  # fmt: skip


def merge(to: Fix, mask: int, new: dict) -> bool:
    """Merge one sentence's data (``new``, set under ``mask``) into the fix ``to``; whether
    anything in it changed."""
    changed = False
    for name, value in new.items():
        if name in GATE and getattr(to, name) != value:
            setattr(to, name, value)
            changed = True
    if mask & TIME_SET and "time_ns" not in new and to.time_ns is not None:
        to.time_ns, changed = None, True
    if mask & LATLON_SET and "lat" not in new and to.lat is not None:
        to.lat = to.lon = None
        changed = True
    if mask & MODE_SET:
        mode = new.get("mode", MODE_NOT_SEEN)
        if to.mode != mode:
            to.mode, changed = mode, True
    if mask & STATUS_SET:
        status = new.get("status", STATUS_UNK)
        if to.status < status:
            to.status, changed = status, True
    if "epx" in new and "epy" in new:
        to.epx, to.epy = new["epx"], new["epy"]
        changed = True
    if "dgps_age" in new and (to.dgps_age, to.dgps_station) != (
        new["dgps_age"],
        new["dgps_station"],
    ):
        to.dgps_age, to.dgps_station = new["dgps_age"], new["dgps_station"]
        changed = True
    return changed
