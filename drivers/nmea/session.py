"""One NMEA receiver's state, updated sentence by sentence the way gpsd updates it.

:meth:`Session.process` is gpsd's ``nmea_parse`` followed by the part of ``gpsd_poll``
that merges the result: the sentence's handler fills new data; a sentence whose time of
day differs from the last registered one starts a new cycle (gpsd's CLEAR_IS: the fix and,
unless the sentence gave some, the DOPs are cleared); a sentence that would lower a 3D fix
to 2D while the fix had an altitude keeps it 3D; the data is merged into the fix; a
complete GSV set computes the missing DOPs; the error model runs. The current fix
(:attr:`Session.fix`) is then what gpsd would report in a TPV.

Dates: RMC and ZDA set the date; a time of day earlier than the previous one moves the
date a day on (gpsd's midnight wrap); nothing has a time before the first date. Dates
before ``rollover_before_year`` move forward by 1024 weeks (GPS week-counter rollover).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

from drivers.nmea import handlers as h
from drivers.nmea import proprietary as p
from drivers.nmea.errmodel import earth_distance, error_model
from drivers.nmea.fields import fnum, hhmmss_ns
from drivers.nmea.fixstate import (
    CLEAR_IS,
    DOP_SET,
    LATLON_SET,
    MODE_3D,
    MODE_NO_FIX,
    MODE_SET,
    REPORT_IS,
    SATELLITE_SET,
    STATUS_SET,
    TIME_SET,
    Fix,
    merge,
)
from drivers.nmea.memo import on_clear
from drivers.nmea.sky import Sky

ROLLOVER_S = 1024 * 7 * 86400
DAY_NS = 86_400 * 1_000_000_000
_PAD = tuple(("",) * k for k in range(20))  # fields a short sentence is padded with
# what merge() may change with no data in the sentence (a clear time, position, mode)
_MERGED = TIME_SET | LATLON_SET | MODE_SET | STATUS_SET

Handler = Callable[..., int]


def _sky_gsa(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    return st.sky.gsa(talker, f if len(f) == n else f[:n], new, st.latch_mode)


def _sky_gsv(st: Session, talker: str, f: tuple[str, ...], new: dict, n: int) -> int:
    mask, more = st.sky.gsv(talker, f if len(f) == n else f[:n])
    st.gsx_more = more
    return mask


# type -> (handler, fewest fields gpsd accepts (address included), fields the handler reads)
HANDLERS: dict[str, tuple[Handler, int, int]] = {
    "GGA": (h.gga, 13, 14),
    "RMC": (h.rmc, 8, 12),
    "GLL": (h.gll, 7, 7),
    "GNS": (h.gns, 13, 13),
    "GSA": (_sky_gsa, 18, 0),
    "GSV": (_sky_gsv, 0, 0),
    "VTG": (h.vtg, 5, 9),
    "GST": (h.gst, 8, 8),
    "GBS": (h.gbs, 7, 4),
    "ZDA": (h.zda, 4, 4),
    "PGRME": (p.pgrme, 7, 6),
    "PGRMF": (p.pgrmf, 15, 15),
    "PGRMZ": (p.pgrmz, 4, 3),
    "PSTI": (p.psti, 2, 15),
}
TYPES = tuple(k for k in HANDLERS if not k.startswith("P"))


@lru_cache(maxsize=64)
def days_from_civil(y: int, m: int, d: int) -> int:
    """Days since 1970-01-01 of a (proleptic Gregorian) date; d may run past the month."""
    y -= m <= 2
    era = (y if y >= 0 else y - 399) // 400
    yoe = y - era * 400
    doy = (153 * (m + (-3 if m > 2 else 9)) + 2) // 5
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468 + d - 1


on_clear(days_from_civil.cache_clear)


class Session:
    """gpsd's view of one NMEA receiver (see the module docstring)."""

    def __init__(self, rollover_before_year: int | None = None) -> None:
        self.rollover_before_year = rollover_before_year
        self.fix = Fix()
        # gpsd's lastfix (the fix after the last sentence with a time) and oldfix (the
        # previous epoch's): the fix objects themselves, a new cycle starts a new one
        self.lastfix = Fix()
        self.oldfix = self.lastfix
        self.sky = Sky()
        self.date: tuple[int, int, int] | None = None
        self.day = 0  # days since 1970 of the date, plus midnight wraps
        self.tod_ns: int | None = None
        self.this_frac: float | None = None
        self.last_frac: float | None = None
        self.latch_frac = False
        self.gsx_more = False
        self.last_gga_talker = ""
        self.last_gga_time = ""
        self.latch_mode = False
        self.gst: tuple[float | None, ...] | None = None
        self.gst_tod: int | None = None
        self.leap_seconds: int | None = None
        self.malformed = 0
        self.quality: int | None = None  # this cycle's GGA: fix quality, satellites used
        self.gga_sats: int | None = None
        self._dist: tuple[tuple, float | None] = ((), None)
        self._dops: dict = {}  # the DOPs the error model last saw
        self._unnormed = False  # a track the error model left outside 0-360 degrees

    # ------------------------------------------------------------ for handlers
    def merge_hhmmss(self, field: str) -> bool:
        ns = hhmmss_ns(field)
        if ns is None:
            return False
        if self.tod_ns is not None and ns // 3_600_000_000_000 < self.tod_ns // 3_600_000_000_000:
            self.day += 1  # the hour went back: past midnight
        self.tod_ns = ns
        return True

    def set_date(self, date: tuple[int, int, int]) -> None:
        self.date = date
        self.day = days_from_civil(*date)
        if self.rollover_before_year is not None and date[0] < self.rollover_before_year:
            self.day += ROLLOVER_S // 86400

    def register_time(self, field: str) -> None:
        self.last_frac = self.this_frac
        self.this_frac = fnum(field)
        self.latch_frac = True

    def time_lost(self) -> int:
        """A no-fix sentence without a time: the date is forgotten, the report forced."""
        self.date = None
        self.tod_ns = None
        return REPORT_IS | TIME_SET

    def hhmmss(self) -> str:
        s = (self.tod_ns or 0) // 1_000_000_000
        return f"{s // 3600:02d}{s // 60 % 60:02d}{s % 60:02d}"

    def sky_used(self) -> int:
        return self.sky.used_count

    def distance(self, lat1, lon1, lat2, lon2) -> float | None:
        """earth_distance, remembered for the last pair of points (asked once a sentence)."""
        key = (lat1, lon1, lat2, lon2)
        if self._dist[0] != key:
            self._dist = (key, earth_distance(lat1, lon1, lat2, lon2))
        return self._dist[1]

    # ------------------------------------------------------------ one sentence
    def process(self, talker: str, kind: str, fields: tuple[str, ...]) -> int:
        """Apply one sentence (type ``kind``: "GGA", or "PGRMZ" for proprietary ones);
        returns gpsd's mask of what it set (CLEAR_IS when it started a new cycle)."""
        mask, new = self.parse(talker, kind, fields)
        self.apply(mask, new)
        return mask

    def parse(self, talker: str, kind: str, fields: tuple[str, ...]) -> tuple[int, dict]:
        """A sentence's data and mask. The fix, the DOPs and the satellites used are not
        touched yet (see :meth:`apply`), so the previous epoch can still be reported."""
        entry = HANDLERS.get(kind)
        mask = 0
        new: dict = {}
        self.latch_frac = self.gsx_more = False
        if entry is not None:
            handler, fewest, width = entry
            n = len(fields)
            if n + 1 < fewest:
                self.malformed += 1
            else:
                if n < width:
                    fields = fields + _PAD[width - n]
                mask = handler(self, talker, fields, new, n)
        sky = self.sky
        if kind != "GSV":
            sky.last_gsv_talker = ""
        if kind != "GSA":
            sky.last_gsa_talker = ""
        if mask & TIME_SET:
            tod = self.tod_ns
            new["time_ns"] = None if self.date is None or tod is None else self.day * DAY_NS + tod
        if self.latch_frac and not self.gsx_more:
            this, last = self.this_frac, self.last_frac
            if this is None or last is None or abs(this - last) > 0.01:
                mask |= CLEAR_IS
        if (mask & MODE_SET and self.fix.mode == MODE_3D and new.get("mode", 0) != MODE_NO_FIX
                and self._had_altitude()):  # fmt: skip
            new["mode"] = MODE_3D  # do not drop a 3D fix to 2D (RMC says nothing of 3D)
        return mask, new

    def apply(self, mask: int, new: dict) -> None:
        """Merge a parsed sentence into the fix (a new cycle clears it first), then the
        DOPs of a complete GSV set and the error model. The error model is a function of
        the fix, the DOPs and the previous fixes: when a sentence changed none of them
        (a repeated GSA, a ZDA of the same second, a GST) running it again would change
        nothing (but a track still outside 0-360 degrees, which gpsd moves by 360 a run),
        and it is skipped."""
        sky = self.sky
        fix = self.fix
        changed = False
        if mask & CLEAR_IS:
            fix = self.new_cycle(mask & DOP_SET)
            changed = True
        elif mask & TIME_SET and not new.get("time_ns") and self.lastfix is fix:
            self.lastfix = fix.copy()  # this sentence leaves the fix without a time
        if "dop" in new:
            sky.dop.update(new["dop"])
        if "quality" in new:
            self.quality, self.gga_sats = new["quality"], new["gga_sats"]
            if sky.used_count != new["used_count"]:
                sky.used_count = new["used_count"]
                sky.changed = True
        if (new or mask & _MERGED) and merge(fix, mask, new):
            changed = True
        if mask & SATELLITE_SET and sky.view:
            sky.fill_dop()
        # (of the estimates a sentence may give, only GBS and PGRME give epx/epy)
        if changed or sky.dop != self._dops or self._unnormed or "epx" in new or "epy" in new:
            self.model(new)

    def new_cycle(self, keep_dops: int) -> Fix:
        """gpsd's CLEAR_IS: a new fix (the DOPs cleared unless the sentence gave some)."""
        if not keep_dops:
            self.sky.dop.clear()
        fix = self.fix = Fix()
        self.quality = self.gga_sats = None
        return fix

    def model(self, new: dict) -> None:
        """The error model on the merged fix (``new``: what the sentence gave); it keeps
        the DOPs it saw and whether a track is left outside 0-360 degrees (gpsd's error
        model moves such a track by 360 each run, so it is not the same after another)."""
        error_model(self, new)

    def _had_altitude(self) -> bool:
        last, old = self.lastfix, self.oldfix
        return not (
            last.alt_hae is None
            and old.alt_hae is None
            and last.alt_msl is None
            and old.alt_msl is None
        )

    def time_ns(self) -> int | None:
        """UTC of the current date and time of day (ns since 1970); None without a date."""
        if self.date is None or self.tod_ns is None:
            return None
        return self.day * DAY_NS + self.tod_ns
